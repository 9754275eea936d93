// libFuzzer target: the command-line handling of one envkit tool, in process.
//
// The tool's own source (tools/<tool>.cpp, probes/envprobe.cpp) is compiled into this target with
// -Dmain=envkit_tool_main (tests/fuzz/CMakeLists.txt), so the fuzzer drives exactly the code of the shipped
// binary: CLI11 parsing, validators, the combination checks, and the run itself on small files.
//
// Input: the arguments, separated by '\n' or '\0' (at most 32 of at most 256 bytes). argv[0] is the tool name.
// Confinement: the process works in a private scratch directory (chdir) holding small seed maps (in.exr,
// cube.exr, face_%.exr, ...; see write_seed_files); every '/' in an argument becomes '_', so no argument can name
// a path outside that directory (".." is a directory, which the tools refuse to write). Files the run creates are
// removed afterwards and seed files it replaced (--force) are restored, so runs do not depend on each other.
// Cost limit: inputs with a number above kMaxNumber (or written with an exponent or a 0x prefix) are skipped, so
// that "--size 100000" does not make every run allocate gigabytes; without --size, envprobe gets "--size 16x8"
// appended (its default is 1024x512). See tests/fuzz/README.md.
#include "fuzz_support.h"

#include <envkit/envmap.h>
#include <envkit/image.h>
#if __has_include(<envkit/env_tables.h>)
#include <envkit/env_tables.h>
#define ENVKIT_FUZZ_HAVE_TABLES 1
#endif
#include <envkit/image_io.h>
#include <envkit/latlong.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#ifndef ENVKIT_FUZZ_TOOL
#error "ENVKIT_FUZZ_TOOL must name the tool (set by tests/fuzz/CMakeLists.txt)"
#endif

int envkit_tool_main(int argc, char** argv);

namespace {

namespace fs = std::filesystem;
constexpr std::size_t kMaxArgs = 32, kMaxArgLength = 256;
constexpr long kMaxNumber = 512;

struct Seed {
  std::string bytes;
  struct stat st {};
};
std::map<std::string, Seed> g_seeds;  // file name -> contents and stat after writing

envkit::Image gradient(int w, int h, int channels, float scale = 1.0f) {
  envkit::Image img(w, h, channels);
  img.channel_names = envkit::default_channel_names(channels);
  if (channels == 2 || channels == 4) img.alpha_channel = channels - 1;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c)
        img.at(x, y, c) = c == img.alpha_channel ? 1.0f : scale * (0.1f + float(x + 2 * y + c) / float(w + h));
  return img;
}

void write_tagged(const std::string& name, const envkit::Image& img, const std::string& kind) {
  envkit::WriteOptions opt;
  if (!kind.empty()) opt.metadata["envkit:parameterization"] = kind;
  envkit::write_image(name, img, opt);
}

void write_seed_files() {
  write_tagged("in.exr", gradient(16, 8, 3), "latlong");
  write_tagged("plain.exr", gradient(16, 8, 3), "");
  write_tagged("in.hdr", gradient(16, 8, 3), "");
  write_tagged("in.png", gradient(16, 8, 4), "");
  write_tagged("gray.exr", gradient(16, 8, 1), "");
  write_tagged("neg.exr", gradient(16, 8, 3, -1.0f), "latlong");
  write_tagged("cube.exr", gradient(4, 24, 3), "cube");
  write_tagged("cross.exr", gradient(16, 12, 3), "");
  write_tagged("sq.exr", gradient(8, 8, 3), "");
  write_tagged("one.exr", gradient(1, 1, 3), "");
  write_tagged("odd.exr", gradient(7, 5, 3), "");
  envkit::Image ball = gradient(16, 16, 3);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      if ((x - 7.5) * (x - 7.5) + (y - 7.5) * (y - 7.5) > 64.0)
        for (int c = 0; c < 3; ++c) ball.at(x, y, c) = 0.0f;
  write_tagged("ball.exr", ball, "");
  for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"}) write_tagged(std::string("face_") + f + ".exr", gradient(4, 4, 3), "");
#ifdef ENVKIT_FUZZ_HAVE_TABLES
  {  // a table file for envsample / envinfo / envrender
    envkit::EnvMap map;
    map.image = gradient(16, 8, 3);
    map.param = std::make_unique<envkit::LatLongMap>(16, 8);
    envkit::EnvTables::bake(map, envkit::BakeOptions{}, "in.exr").save("in.envtbl");
  }
#endif
  std::ofstream("junk.exr", std::ios::binary) << "not an image";
  std::ofstream("empty.exr", std::ios::binary);
  fs::create_directories("dir.exr");
  for (const auto& e : fs::directory_iterator(".")) {
    if (!e.is_regular_file()) continue;
    Seed s;
    std::ifstream in(e.path(), std::ios::binary);
    s.bytes.assign(std::istreambuf_iterator<char>(in), {});
    ::stat(e.path().c_str(), &s.st);
    g_seeds[e.path().filename().string()] = std::move(s);
  }
}

// Removes what the run created and restores seed files it replaced or removed.
void restore_scratch() {
  for (const auto& e : fs::directory_iterator(".")) {
    const std::string name = e.path().filename().string();
    if (name == "dir.exr") continue;
    if (!g_seeds.count(name)) fs::remove_all(e.path());
  }
  fs::create_directories("dir.exr");
  for (auto& [name, seed] : g_seeds) {
    struct stat st {};
    if (::stat(name.c_str(), &st) == 0 && st.st_ino == seed.st.st_ino && st.st_size == seed.st.st_size &&
        st.st_mtim.tv_sec == seed.st.st_mtim.tv_sec && st.st_mtim.tv_nsec == seed.st.st_mtim.tv_nsec)
      continue;
    fs::remove_all(name);
    std::ofstream(name, std::ios::binary) << seed.bytes;
    ::stat(name.c_str(), &seed.st);
  }
}

// True when the argument holds a number that could make the run expensive (see the file comment).
bool too_costly(const std::string& a) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    const char c = a[i];
    if (c >= '0' && c <= '9') {
      long v = 0;
      std::size_t j = i;
      while (j < a.size() && a[j] >= '0' && a[j] <= '9' && v <= kMaxNumber) v = v * 10 + (a[j++] - '0');
      if (v > kMaxNumber) return true;
      if (c == '0' && i + 1 < a.size() && (a[i + 1] == 'x' || a[i + 1] == 'X' || a[i + 1] == 'b' || a[i + 1] == 'o'))
        return true;
      if (j < a.size() && (a[j] == 'e' || a[j] == 'E')) return true;
      while (j < a.size() && a[j] >= '0' && a[j] <= '9') ++j;
      i = j;
    }
  }
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const fs::path& dir = envkit::fuzz::scratch_dir(ENVKIT_FUZZ_TOOL);
  fs::current_path(dir);
  ::unsetenv("OCIO");
  ::unsetenv("ENVKIT_OCIO_CONFIG");
  write_seed_files();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::string> args{ENVKIT_FUZZ_TOOL};
  std::string cur;
  for (std::size_t i = 0; i <= size; ++i) {
    if (i == size || data[i] == '\n' || data[i] == '\0') {
      if (args.size() > kMaxArgs || cur.size() > kMaxArgLength) return 0;
      args.push_back(cur);
      cur.clear();
    } else {
      cur += data[i] == '/' ? '_' : static_cast<char>(data[i]);
    }
  }
  if (size == 0) args.pop_back();  // no argument at all
  bool has_size = false;
  for (const auto& a : args) {
    if (too_costly(a)) return 0;
    has_size = has_size || a.rfind("--size", 0) == 0;
  }
  if (std::string(ENVKIT_FUZZ_TOOL) == "envprobe" && !has_size) args.insert(args.end(), {"--size", "16x8"});

  std::vector<std::vector<char>> storage;
  std::vector<char*> argv;
  for (const auto& a : args) storage.emplace_back(a.c_str(), a.c_str() + a.size() + 1);
  for (auto& s : storage) argv.push_back(s.data());
  argv.push_back(nullptr);
  {
    envkit::fuzz::SilenceStreams quiet;
    const int code = envkit_tool_main(static_cast<int>(args.size()), argv.data());
    // The documented exit codes are 0..3 for every tool.
    if (code < 0 || code > 3) __builtin_trap();
  }
  restore_scratch();
  return 0;
}
