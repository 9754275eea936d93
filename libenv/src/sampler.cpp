#include <envkit/sampler.h>

#include <array>

namespace envkit {

namespace {

std::uint32_t reverse_bits(std::uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
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
constexpr std::array<std::uint32_t, 32> kSobol1 = sobol_dimension1();

std::uint32_t sobol1(std::uint32_t index) {
  std::uint32_t result = 0;
  for (int k = 0; index != 0; index >>= 1, ++k)
    if (index & 1u) result ^= kSobol1[k];
  return result;
}

/// 32 scrambled bits + 21 hashed low bits -> a double in [0, 1).
double to_unit(std::uint32_t high, std::uint32_t low_seed) {
  const std::uint64_t bits = (std::uint64_t(high) << 21) | (hash_u32(low_seed) >> 11);
  return double(bits) * 0x1p-53;
}

}  // namespace

std::uint32_t hash_u32(std::uint32_t x) {
  // lowbias32 (Chris Wellons)
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

std::uint32_t hash_combine(std::uint32_t seed, std::uint32_t value) {
  return hash_u32(seed ^ (value + 0x9e3779b9u + (seed << 6) + (seed >> 2)));
}

OwenSobolSampler::OwenSobolSampler(std::uint32_t seed, int px, int py)
    : pixel_seed_(hash_combine(hash_combine(hash_u32(seed), std::uint32_t(px)), std::uint32_t(py))) {}

Vec2 OwenSobolSampler::next_2d() {
  const std::uint32_t dim_seed = hash_combine(pixel_seed_, dimension_++);
  const std::uint32_t shuffled = nested_uniform_scramble(index_, dim_seed);
  const std::uint32_t x = nested_uniform_scramble(reverse_bits(shuffled), hash_combine(dim_seed, 1u));
  const std::uint32_t y = nested_uniform_scramble(sobol1(shuffled), hash_combine(dim_seed, 2u));
  const std::uint32_t low = hash_combine(dim_seed, index_);
  return Vec2(to_unit(x, low), to_unit(y, hash_combine(low, 3u)));
}

}  // namespace envkit
