#pragma once
/// @file merl.h
/// Reader of isotropic BRDFs in the MERL binary format (Matusik, Pfister, Brand and McMillan 2003, "A Data-Driven
/// Reflectance Model"; the format of the MERL BRDF database, e.g. "blue-fabric.binary"), and the format's
/// Rusinkiewicz half/difference coordinates (shared with the tests that write such files).
///
/// The format: three little-endian int32 dimensions (90, 90, 180 = theta_half, theta_diff, phi_diff cells), then
/// 3 x 90 x 90 x 180 little-endian doubles: all red values, then all green, then all blue, each block indexed
/// [theta_half][theta_diff][phi_diff] (phi_diff fastest). A value times the channel's scale (1/1500, 1.15/1500,
/// 1.66/1500) is f in 1/sr. Negative values mark cells the measurement did not reach.
///
/// Cells (the reference code's lookup_brdf_val), angles in radians:
/// - theta_half in [0, pi/2]: cell floor(sqrt(theta_half / (pi/2)) x 90), non-linear, finer near the specular peak;
/// - theta_diff in [0, pi/2]: cell floor(theta_diff / (pi/2) x 90);
/// - phi_diff in [0, pi): cell floor(phi_diff / pi x 180); an isotropic, reciprocal BRDF repeats with period pi in
///   phi_diff, so phi_diff >= pi (or < 0) is taken modulo pi.
/// envkit places each value at the CENTRE of its cell (the reference code's nearest lookup is exact there).
#include <envkit/core/vec.h>

#include <cstddef>
#include <string>
#include <vector>

namespace envkit::render::merl {

inline constexpr int kThetaHalfCells = 90;
inline constexpr int kThetaDiffCells = 90;
inline constexpr int kPhiDiffCells = 180;
inline constexpr std::size_t kCells = std::size_t(kThetaHalfCells) * kThetaDiffCells * kPhiDiffCells;
/// Per-channel scale from the stored values to f (1/sr).
inline constexpr double kScale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};

/// Index of cell (theta_half, theta_diff, phi_diff) within one channel's block.
inline std::size_t cell_index(int th, int td, int pd) {
  return (std::size_t(th) * kThetaDiffCells + std::size_t(td)) * kPhiDiffCells + std::size_t(pd);
}

/// The angles of a cell's centre (radians).
double theta_half_of_cell(int th);
double theta_diff_of_cell(int td);
double phi_diff_of_cell(int pd);

/// Rusinkiewicz coordinates of a pair of directions in the local frame (z = normal): the half vector h of wo and wi
/// at (theta_half, phi_half), and wi seen in the frame where h is the pole (theta_diff, phi_diff); phi_diff folded
/// into [0, pi). False when wo and wi are opposite.
struct HalfDiff {
  double theta_half = 0.0, theta_diff = 0.0, phi_diff = 0.0;
};
bool half_diff(const Vec3& wo, const Vec3& wi, HalfDiff& out);

/// The inverse: a pair (wo, wi) with those coordinates and phi_half = 0 (unit vectors; either may point below the
/// horizon when theta_half + theta_diff > pi/2).
void directions(const HalfDiff& hd, Vec3& wo, Vec3& wi);

/// f in RGB (1/sr) per cell, interleaved (3 floats per cell, cell_index() order), with the channel scales and
/// `scale` applied; cells the measurement did not reach (negative values) hold 0.
struct Data {
  std::vector<float> rgb;
  std::size_t missing = 0;  ///< cells with a negative value in some channel
};

/// Reads a MERL binary file. Throws Error("<file>: <problem>") for a file that does not exist or is not a regular
/// file, a short header, dimensions other than 90 x 90 x 180, a size that does not match them (truncated or with
/// trailing bytes), a NaN or infinite value, or no value >= 0 anywhere.
Data read(const std::string& file, const Vec3& scale = Vec3(1.0));

}  // namespace envkit::render::merl
