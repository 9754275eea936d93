// libFuzzer target: VALUES inside a valid table file, behind valid checksums (EnvTables::load's validation).
//
// fuzz_tables mutates bytes, and nearly every mutation is caught by a section checksum. Here the fuzz input is a
// short program of patches applied to a valid baked table file: each record names a section, an offset in it and
// a hostile value (NaN, -1, 0, -0, +-Inf, a denormal, FLT_MAX, 2, 1/2, raw bits, as a float, double or int32).
// The patched file is then resealed (every checksum recomputed: reseal_table_file) so only the value validation
// stands between it and the samplers. A load must either throw envkit::Error naming the file, or give tables whose
// samples have finite, positive pdfs, texels inside the grid, finite unit directions and pdf(direction) finite.
//
// Byte 0 chooses the file (even: 16 x 8, every method and the compensated twins; odd: a stored sun split), then
// records of 7 bytes, up to 16: section index (mod the section count), value kind, byte offset
// (uint32 little endian, mod the section size, rounded down to the value's alignment), one spare byte of raw bits.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>
#include <envkit/tables/sun_split.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "seed_tables.h"

namespace {

using envkit::fuzz::finding;

std::vector<std::byte> g_seeds[2];  // valid table files (seed_tables.h): every method; a stored sun split

template <class Write>
std::vector<std::byte> bake_seed(const Write& write_seed) {
  const std::string path = (envkit::fuzz::scratch_dir() / "seed.envtables").string();
  write_seed(path);
  std::ifstream f(path, std::ios::binary);
  const std::vector<char> bytes((std::istreambuf_iterator<char>(f)), {});
  std::vector<std::byte> out(bytes.size());
  std::memcpy(out.data(), bytes.data(), bytes.size());
  return out;
}

template <class T>
void put(std::vector<std::byte>& file, std::size_t at, T value) {
  std::memcpy(file.data() + at, &value, sizeof(T));
}

// Writes value kind `kind` at `at` (already aligned and inside the section); returns the value's size.
void patch(std::vector<std::byte>& file, std::size_t begin, std::size_t size, std::uint8_t kind, std::uint32_t offset,
           std::uint8_t raw) {
  static const float floats[] = {std::numeric_limits<float>::quiet_NaN(),
                                 -1.0f,
                                 0.0f,
                                 -0.0f,
                                 std::numeric_limits<float>::infinity(),
                                 -std::numeric_limits<float>::infinity(),
                                 FLT_TRUE_MIN,
                                 FLT_MAX,
                                 2.0f,
                                 0.5f,
                                 1e-30f,
                                 1.0f};
  static const double doubles[] = {std::numeric_limits<double>::quiet_NaN(), -1.0,  0.0, 1e300,
                                   std::numeric_limits<double>::infinity(),  1e-300};
  static const std::int32_t ints[] = {-1, 0, 1, 0x7fffffff, std::int32_t(0x80000000u), 65536};
  constexpr int nf = std::size(floats), nd = std::size(doubles), ni = std::size(ints);
  const int k = kind % (nf + nd + ni + 1);
  const std::size_t width = k < nf ? 4 : k < nf + nd ? 8 : 4;
  if (size < width) return;
  const std::size_t at = begin + (std::size_t(offset) % (size - width + 1)) / width * width;
  if (k < nf)
    put(file, at, floats[k]);
  else if (k < nf + nd)
    put(file, at, doubles[k - nf]);
  else if (k < nf + nd + ni)
    put(file, at, ints[k - nf - nd]);
  else
    file[at] = std::byte(raw);  // one raw byte
}

// 64 samples of `d` (one of the tables or a stored sun split's part): finite positive pdfs, texels inside the grid,
// unit directions, pdf(direction) finite.
void check_distribution(const envkit::SphericalDistribution& d, const std::string& name) {
  const int W = d.distribution().width(), H = d.distribution().height();
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) {
      const envkit::Vec2 u((i + 0.37) / 8.0, (j + 0.61) / 8.0);
      const std::string at = name + " at u = (" + std::to_string(u.x) + ", " + std::to_string(u.y) + ")";
      const envkit::DirectionSample s = d.sample(u);
      if (!(std::isfinite(s.pdf) && s.pdf > 0.0))
        finding("a drawn sample with a pdf that is not finite and > 0: " + at + " gives texel (" + std::to_string(s.x) +
                ", " + std::to_string(s.y) + ") with pdf " + std::to_string(s.pdf));
      if (s.x < 0 || s.x >= W || s.y < 0 || s.y >= H) finding("a sample outside the grid: " + at);
      const double len =
          std::sqrt(s.direction.x * s.direction.x + s.direction.y * s.direction.y + s.direction.z * s.direction.z);
      if (!(std::abs(len - 1.0) < 1e-6)) finding("a sample direction that is not a unit vector: " + at);
      const double p = d.pdf(s.direction);
      if (!(std::isfinite(p) && p >= 0.0)) finding("pdf(direction) not finite and >= 0: " + at);
      const envkit::TexelSample t = d.distribution().sample_texel(u);
      if (t.x < 0 || t.x >= W || t.y < 0 || t.y >= H) finding("sample_texel outside the grid: " + at);
    }
}

void check_tables(const envkit::EnvTables& tables) {
  for (auto method : {envkit::SamplingMethod::Cdf, envkit::SamplingMethod::Alias, envkit::SamplingMethod::Hierarchical})
    for (bool comp : {false, true}) {
      const std::string name = std::string(envkit::method_name(method)) + (comp ? " (compensated)" : "");
      if (const envkit::SphericalDistribution* d = tables.distribution(method, comp)) check_distribution(*d, name);
      if (const auto split = tables.stored_sun_split(method, comp); split && *split) {
        check_distribution((*split)->residual(), "the sun split's residual of " + name);
        check_distribution((*split)->sun_distribution(), "the sun split's sun of " + name);
      }
    }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  envkit::fuzz::scratch_dir("table_values");
  g_seeds[0] = bake_seed(envkit::fuzz::write_seed_tables);
  g_seeds[1] = bake_seed(envkit::fuzz::write_sun_seed_tables);
  for (const auto& seed : g_seeds)
    if (envkit::table_file_sections(seed).empty()) finding("a baked seed has no sections");
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  std::vector<std::byte> file = g_seeds[data[0] & 1];
  const std::vector<envkit::TableFileSection> sections = envkit::table_file_sections(file);
  for (std::size_t r = 1; r + 7 <= size && r < 1 + 16 * 7; r += 7) {
    const envkit::TableFileSection& s = sections[data[r] % sections.size()];
    if (s.name == "descriptor") continue;  // JSON text: fuzz_tables and the descriptor checks cover it
    std::uint32_t offset;
    std::memcpy(&offset, data + r + 2, 4);
    patch(file, s.offset, s.size, data[r + 1], offset, data[r + 6]);
  }
  envkit::reseal_table_file(file);
  envkit::fuzz::load_and_check(envkit::fuzz::write_input(file.data(), file.size()), check_tables);
  return 0;
}
