#pragma once
/// @file sampler.h (libenv: used by envsample and envrender)
/// Owen-scrambled Sobol points with deterministic seeds (Burley 2020, "Practical Hash-based Owen Scrambling").
///
/// Each pixel has its own seed (hash of the user seed and the pixel's FULL-image coordinates, so a --crop render
/// reproduces the same pixels as the full render). A pixel's sample i, dimension pair d draws the first two Sobol
/// dimensions (van der Corput and its Pascal-matrix partner, a (0,2)-sequence) at a nested-uniform-scrambled
/// (shuffled) index i' = NUS(i, seed_d), then Owen-scrambles each coordinate with its own seed. Dimension pairs
/// are thus decorrelated by shuffling ("padding", Burley section 4), each pair stratified as a (0,2)-sequence.
/// The 32 Sobol bits are completed to 53 bits with hashed low bits, so u reaches texels far below 2^-32 of a row.
/// Values are in [0, 1).
#include <envkit/core/vec.h>

#include <cstdint>

namespace envkit {

/// 32-bit integer hashes used for seeding (public for tests).
std::uint32_t hash_u32(std::uint32_t x);
std::uint32_t hash_combine(std::uint32_t seed, std::uint32_t value);

class OwenSobolSampler {
 public:
  /// seed: the user's --seed; (px, py): the pixel in full-image coordinates.
  OwenSobolSampler(std::uint32_t seed, int px, int py);

  /// Starts sample `index` of this pixel: dimensions restart at 0.
  void start_sample(std::uint32_t index) {
    index_ = index;
    dimension_ = 0;
  }
  /// The next 2D point (consumes one dimension pair).
  Vec2 next_2d();
  /// The next 1D value (consumes one dimension pair): next_2d().x without computing y.
  double next_1d();

  /// Several points of one sample from the same dimension pairs (a shading point's M light samples): reserve(n)
  /// consumes n pairs and returns the first; point_2d(d, k, m) is point k (0 <= k < m) of pair d, index
  /// sample * m + k of its sequence. So the m points of every sample of a pixel are together one stratified
  /// sequence of spp x m points, rather than m sequences of spp points, one per pair. (Indices wrap at 2^32: points
  /// stay uniform, later ones repeat earlier ones.)
  std::uint32_t reserve(std::uint32_t pairs) {
    const std::uint32_t first = dimension_;
    dimension_ += pairs;
    return first;
  }
  Vec2 point_2d(std::uint32_t dimension, std::uint32_t k, std::uint32_t m) const;
  double point_1d(std::uint32_t dimension, std::uint32_t k, std::uint32_t m) const;

 private:
  double first_coordinate(std::uint32_t dim_seed, std::uint32_t shuffled, std::uint32_t low) const;

  std::uint32_t pixel_seed_;
  std::uint32_t index_ = 0;
  std::uint32_t dimension_ = 0;
};

}  // namespace envkit
