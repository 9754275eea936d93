/// MERL binary BRDF files (see merl.h).
#include "merl.h"

#include <envkit/core/error.h>
#include <envkit/core/input_checks.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace envkit::render::merl {

static_assert(std::endian::native == std::endian::little, "the MERL format is little-endian");

double theta_half_of_cell(int th) {
  const double u = (th + 0.5) / kThetaHalfCells;
  return u * u * (kPi / 2.0);
}
double theta_diff_of_cell(int td) { return (td + 0.5) / kThetaDiffCells * (kPi / 2.0); }
double phi_diff_of_cell(int pd) { return (pd + 0.5) / kPhiDiffCells * kPi; }

bool half_diff(const Vec3& wo, const Vec3& wi, HalfDiff& out) {
  Vec3 h = wo + wi;
  const double len = h.length();
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  h /= len;
  out.theta_half = std::acos(std::clamp(h.z, -1.0, 1.0));
  // wi rotated by -phi_half about z, then by -theta_half about y: h becomes the pole.
  const double rxy = std::sqrt(h.x * h.x + h.y * h.y);
  const double cp = rxy > 0.0 ? h.x / rxy : 1.0, sp = rxy > 0.0 ? h.y / rxy : 0.0;
  const double ct = h.z, st = rxy;
  const double x1 = cp * wi.x + sp * wi.y, y1 = -sp * wi.x + cp * wi.y;
  const double x2 = ct * x1 - st * wi.z, z2 = st * x1 + ct * wi.z;
  out.theta_diff = std::acos(std::clamp(z2, -1.0, 1.0));
  double phi = std::atan2(y1, x2);  // (-pi, pi]
  if (phi < 0.0) phi += kPi;
  if (phi >= kPi) phi -= kPi;
  out.phi_diff = std::clamp(phi, 0.0, kPi);
  return true;
}

void directions(const HalfDiff& hd, Vec3& wo, Vec3& wi) {
  // wi in h's frame, then rotated by theta_half about y (phi_half = 0); wo is its mirror image about h.
  const double sd = std::sin(hd.theta_diff), cd = std::cos(hd.theta_diff);
  const Vec3 d(sd * std::cos(hd.phi_diff), sd * std::sin(hd.phi_diff), cd);
  const double ct = std::cos(hd.theta_half), st = std::sin(hd.theta_half);
  wi = Vec3(ct * d.x + st * d.z, d.y, -st * d.x + ct * d.z);
  const Vec3 h(st, 0.0, ct);
  wo = h * (2.0 * (wi ^ h)) - wi;
}

namespace {

constexpr std::size_t kHeaderBytes = 3 * sizeof(std::int32_t);
constexpr std::uint64_t kFileBytes = kHeaderBytes + 3 * kCells * sizeof(double);
constexpr const char* kChannelNames[3] = {"red", "green", "blue"};

[[noreturn]] void fail(const std::string& file, const std::string& problem) { throw Error(file + ": " + problem); }

}  // namespace

Data read(const std::string& file, const Vec3& scale) {
  require_regular_file(file);
  std::error_code ec;
  const std::uint64_t size = std::filesystem::file_size(file, ec);
  if (ec) fail(file, "cannot read the size: " + ec.message());
  std::ifstream in(file, std::ios::binary);
  if (!in) fail(file, "cannot open: " + std::string(std::strerror(errno)));
  std::int32_t dims[3] = {0, 0, 0};
  if (size < kHeaderBytes || !in.read(reinterpret_cast<char*>(dims), kHeaderBytes))
    fail(file, "not a MERL BRDF: " + std::to_string(size) + " bytes, shorter than the 12-byte header");
  if (dims[0] != kThetaHalfCells || dims[1] != kThetaDiffCells || dims[2] != kPhiDiffCells)
    fail(file, "not a MERL BRDF: header dimensions " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
                   " x " + std::to_string(dims[2]) + ", expected 90 x 90 x 180");
  if (size < kFileBytes)
    fail(file,
         "truncated: " + std::to_string(size) + " bytes, 90 x 90 x 180 x 3 values need " + std::to_string(kFileBytes));
  if (size > kFileBytes)
    fail(file, std::to_string(size) + " bytes, more than the " + std::to_string(kFileBytes) +
                   " that 90 x 90 x 180 x 3 values take (not a MERL BRDF?)");
  Data data;
  data.rgb.assign(3 * kCells, 0.0f);
  std::vector<double> block(kCells);
  std::vector<unsigned char> missing(kCells, 0);
  bool any_positive = false;
  for (int c = 0; c < 3; ++c) {
    if (!in.read(reinterpret_cast<char*>(block.data()), std::streamsize(kCells * sizeof(double))))
      fail(file, "truncated: the read stopped inside the values");
    const double s = kScale[c] * (std::isfinite(scale[c]) ? std::max(0.0, scale[c]) : 0.0);
    for (std::size_t i = 0; i < kCells; ++i) {
      const double v = block[i];
      if (!std::isfinite(v))
        fail(file, std::string(std::isnan(v) ? "NaN" : "infinite") + " value at cell " + std::to_string(i) +
                       " of the " + kChannelNames[c] + " block");
      if (v < 0.0) missing[i] = 1;
      if (v > 0.0) any_positive = true;
      data.rgb[3 * i + std::size_t(c)] = float(std::max(0.0, v) * s);
    }
  }
  if (!any_positive) fail(file, "no positive value: every cell is missing (negative) or zero");
  for (std::size_t i = 0; i < kCells; ++i) {
    if (!missing[i]) continue;
    ++data.missing;
    for (int c = 0; c < 3; ++c) data.rgb[3 * i + std::size_t(c)] = 0.0f;
  }
  return data;
}

}  // namespace envkit::render::merl
