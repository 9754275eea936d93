#include <envkit/sampling/sampler.h>

#include <array>

namespace envkit {

namespace {

constexpr std::array<std::uint8_t, 256> reversed_bytes() {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v)
    for (int k = 0; k < 8; ++k)
      if (v & (1 << k)) t[v] = static_cast<std::uint8_t>(t[v] | (0x80 >> k));
  return t;
}
constexpr std::array<std::uint8_t, 256> kReversedBytes = reversed_bytes();

std::uint32_t reverse_bits(std::uint32_t x) {
  return (std::uint32_t(kReversedBytes[x & 0xFFu]) << 24) | (std::uint32_t(kReversedBytes[(x >> 8) & 0xFFu]) << 16) |
         (std::uint32_t(kReversedBytes[(x >> 16) & 0xFFu]) << 8) | std::uint32_t(kReversedBytes[x >> 24]);
}

// lowbias32 (Chris Wellons), inlined into the sampler; hash_u32 below is the same function.
inline std::uint32_t lowbias32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

inline std::uint32_t combine(std::uint32_t seed, std::uint32_t value) {
  return lowbias32(seed ^ (value + 0x9e3779b9u + (seed << 6) + (seed >> 2)));
}

/// Laine-Karras style permutation, the improved constants of Burley 2020 (listing 3).
std::uint32_t laine_karras_permutation(std::uint32_t x, std::uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

/// Owen scrambling of the bits of x read as a binary fraction (most significant bit first).
std::uint32_t nested_uniform_scramble(std::uint32_t x, std::uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

/// Generator matrix columns of Sobol dimension 1 (primitive polynomial x + 1): v_k = v_{k-1} ^ (v_{k-1} >> 1).
constexpr std::array<std::uint32_t, 32> sobol_dimension1() {
  std::array<std::uint32_t, 32> v{};
  v[0] = 0x80000000u;
  for (int k = 1; k < 32; ++k) v[k] = v[k - 1] ^ (v[k - 1] >> 1);
  return v;
}

/// The generator matrix times every byte value at each of the four byte positions of an index: the product is
/// linear over GF(2), so four lookups XORed give it for any 32-bit index (the shuffled indices use all 32 bits,
/// where a loop over the set bits takes 32 unpredictable steps).
constexpr std::array<std::array<std::uint32_t, 256>, 4> sobol1_byte_tables() {
  constexpr std::array<std::uint32_t, 32> v = sobol_dimension1();
  std::array<std::array<std::uint32_t, 256>, 4> t{};
  for (int b = 0; b < 4; ++b)
    for (int value = 0; value < 256; ++value)
      for (int k = 0; k < 8; ++k)
        if (value & (1 << k)) t[b][value] ^= v[8 * b + k];
  return t;
}
constexpr std::array<std::array<std::uint32_t, 256>, 4> kSobol1Bytes = sobol1_byte_tables();

std::uint32_t sobol1(std::uint32_t index) {
  return kSobol1Bytes[0][index & 0xFFu] ^ kSobol1Bytes[1][(index >> 8) & 0xFFu] ^
         kSobol1Bytes[2][(index >> 16) & 0xFFu] ^ kSobol1Bytes[3][index >> 24];
}

/// 32 scrambled bits + 21 hashed low bits -> a double in [0, 1).
double to_unit(std::uint32_t high, std::uint32_t low_seed) {
  const std::uint64_t bits = (std::uint64_t(high) << 21) | (lowbias32(low_seed) >> 11);
  return double(bits) * 0x1p-53;
}

}  // namespace

std::uint32_t hash_u32(std::uint32_t x) { return lowbias32(x); }

std::uint32_t hash_combine(std::uint32_t seed, std::uint32_t value) { return combine(seed, value); }

OwenSobolSampler::OwenSobolSampler(std::uint32_t seed, int px, int py)
    : pixel_seed_(hash_combine(hash_combine(hash_u32(seed), std::uint32_t(px)), std::uint32_t(py))) {}

// Sobol dimension 0 is the bit reversal of the index, so its nested uniform scramble
// reverse(LK(reverse(reverse(shuffled)))) is reverse(LK(shuffled)).
double OwenSobolSampler::first_coordinate(std::uint32_t dim_seed, std::uint32_t shuffled, std::uint32_t low) const {
  return to_unit(reverse_bits(laine_karras_permutation(shuffled, combine(dim_seed, 1u))), low);
}

Vec2 OwenSobolSampler::next_2d() { return point_2d(reserve(1), 0, 1); }

double OwenSobolSampler::next_1d() { return point_1d(reserve(1), 0, 1); }

Vec2 OwenSobolSampler::point_2d(std::uint32_t dimension, std::uint32_t k, std::uint32_t m) const {
  const std::uint32_t index = index_ * m + k;
  const std::uint32_t dim_seed = combine(pixel_seed_, dimension);
  const std::uint32_t shuffled = nested_uniform_scramble(index, dim_seed);
  const std::uint32_t low = combine(dim_seed, index);
  const std::uint32_t y = nested_uniform_scramble(sobol1(shuffled), combine(dim_seed, 2u));
  return Vec2(first_coordinate(dim_seed, shuffled, low), to_unit(y, combine(low, 3u)));
}

double OwenSobolSampler::point_1d(std::uint32_t dimension, std::uint32_t k, std::uint32_t m) const {
  const std::uint32_t index = index_ * m + k;
  const std::uint32_t dim_seed = combine(pixel_seed_, dimension);
  return first_coordinate(dim_seed, nested_uniform_scramble(index, dim_seed), combine(dim_seed, index));
}

}  // namespace envkit
