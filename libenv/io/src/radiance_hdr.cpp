// Radiance RGBE/XYZE codec (see image_codecs.h for the format and the conventions kept).
#include <envkit/core/error.h>
#include <envkit/io/image_codecs.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <bit>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <sstream>

namespace envkit {
namespace {

using Bytes = std::span<const unsigned char>;

/// Scanline length range of new-style RLE: the 15-bit length field, and Radiance never run-length encodes scanlines
/// shorter than 8 pixels.
constexpr int kMinRle = 8;
constexpr int kMaxRle = 0x7fff;

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.substr(i);
}

/// Parses whitespace-separated positive finite numbers; false when there are not exactly `count`.
bool parse_positive(const std::string& text, std::size_t count, double* out) {
  std::istringstream in(text);
  in.imbue(std::locale::classic());
  for (std::size_t i = 0; i < count; ++i) {
    if (!(in >> out[i]) || !std::isfinite(out[i]) || out[i] <= 0.0) return false;
  }
  std::string rest;
  return !(in >> rest);
}

/// "-Y 512 +X 1024" and the other seven forms.
bool parse_resolution(const std::string& line, RadianceHeader& h) {
  char s1 = 0, a1 = 0, s2 = 0, a2 = 0;
  long long n1 = 0, n2 = 0;
  std::istringstream in(line);
  in.imbue(std::locale::classic());
  std::string t1, t2, t3, t4, rest;
  if (!(in >> t1 >> t2 >> t3 >> t4) || (in >> rest)) return false;
  if (t1.size() != 2 || t3.size() != 2) return false;
  s1 = t1[0], a1 = t1[1], s2 = t3[0], a2 = t3[1];
  auto number = [](const std::string& t, long long& v) {
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    return r.ec == std::errc() && r.ptr == t.data() + t.size() && v > 0 && v <= std::numeric_limits<int>::max();
  };
  if (!number(t2, n1) || !number(t4, n2)) return false;
  const auto sign_ok = [](char s) { return s == '+' || s == '-'; };
  if (!sign_ok(s1) || !sign_ok(s2)) return false;
  if (!((a1 == 'Y' && a2 == 'X') || (a1 == 'X' && a2 == 'Y'))) return false;
  h.y_major = a1 == 'Y';
  const char ysign = h.y_major ? s1 : s2, xsign = h.y_major ? s2 : s1;
  h.y_decreasing = ysign == '-';
  h.x_decreasing = xsign == '-';
  h.height = static_cast<int>(h.y_major ? n1 : n2);
  h.width = static_cast<int>(h.y_major ? n2 : n1);
  h.resolution = t1 + " " + t2 + " " + t3 + " " + t4;
  return true;
}

// ---- scanlines ------------------------------------------------------------------------------------------------------

/// Where a scanline error is reported from: thrown as "<name>: cannot read pixels: scanline s: problem".
[[noreturn]] void bad_scanline(const std::string& name, int s, const std::string& problem) {
  fail(name, "cannot read pixels (truncated or corrupt file?): scanline " + std::to_string(s) + ": " + problem);
}

bool is_new_style(const unsigned char* p, const unsigned char* end, int length) {
  return length >= kMinRle && length <= kMaxRle && end - p >= 4 && p[0] == 2 && p[1] == 2 && (p[2] & 0x80) == 0;
}

/// One new-style scanline from p: four channel planes, each a sequence of runs (count > 128: count - 128 copies of one
/// byte) and literal dumps (count 1..128 bytes). With Store, writes interleaved RGBE to `rgbe`; without, only checks
/// and skips. Returns the end of the scanline.
template <bool Store>
const unsigned char* new_style(const unsigned char* p, const unsigned char* end, int length, unsigned char* rgbe,
                               const std::string& name, int s) {
  const int stored = (p[2] << 8) | p[3];
  if (stored != length)
    bad_scanline(name, s,
                 "run-length scanline of " + std::to_string(stored) + " pixels, expected " + std::to_string(length));
  p += 4;
  for (int c = 0; c < 4; ++c) {
    int i = 0;
    while (i < length) {
      if (p >= end) bad_scanline(name, s, "data ends inside the scanline");
      const int code = *p++;
      if (code > 128) {
        const int run = code - 128;
        if (run > length - i) bad_scanline(name, s, "run of " + std::to_string(run) + " overflows the scanline");
        if (p >= end) bad_scanline(name, s, "data ends inside the scanline");
        if constexpr (Store) {
          const unsigned char v = *p;
          for (int k = 0; k < run; ++k) rgbe[(i + k) * 4 + c] = v;
        }
        ++p;
        i += run;
      } else {
        if (code == 0) bad_scanline(name, s, "zero-length run");
        if (code > length - i) bad_scanline(name, s, "run of " + std::to_string(code) + " overflows the scanline");
        if (end - p < code) bad_scanline(name, s, "data ends inside the scanline");
        if constexpr (Store)
          for (int k = 0; k < code; ++k) rgbe[(i + k) * 4 + c] = p[k];
        p += code;
        i += code;
      }
    }
  }
  return p;
}

/// An old-style scanline: 4-byte pixels, where (1, 1, 1, n) repeats the previous pixel n << shift times, shift growing
/// by 8 for each consecutive repeat pixel. A flat scanline is the special case without repeats.
const unsigned char* old_style(const unsigned char* p, const unsigned char* end, int length, unsigned char* rgbe,
                               const std::string& name, int s) {
  int i = 0, shift = 0;
  while (i < length) {
    if (end - p < 4) bad_scanline(name, s, "data ends inside the scanline");
    if (p[0] == 1 && p[1] == 1 && p[2] == 1) {
      if (i == 0) bad_scanline(name, s, "repeat code with no previous pixel");
      if (shift > 16) bad_scanline(name, s, "repeat count overflows");
      const long long count = static_cast<long long>(p[3]) << shift;
      if (count > length - i) bad_scanline(name, s, "run of " + std::to_string(count) + " overflows the scanline");
      for (long long k = 0; k < count; ++k, ++i) std::memcpy(rgbe + i * 4, rgbe + (i - 1) * 4, 4);
      shift += 8;
    } else {
      std::memcpy(rgbe + i * 4, p, 4);
      ++i;
      shift = 0;
    }
    p += 4;
  }
  return p;
}

/// 2^(e - 136) for each exponent byte (0 for e = 0: black).
const std::array<float, 256>& exponent_table() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int e = 1; e < 256; ++e) t[static_cast<std::size_t>(e)] = std::ldexp(1.0f, e - 136);
    return t;
  }();
  return table;
}

/// Maps (scanline, position) of the file to the displayed texel index (row 0 at the top).
struct Placement {
  const RadianceHeader& h;
  std::size_t index(int s, int p) const {
    int x, y;  // Radiance picture coordinates: x to the right, y up
    if (h.y_major) {
      y = h.y_decreasing ? h.height - 1 - s : s;
      x = h.x_decreasing ? h.width - 1 - p : p;
    } else {
      x = h.x_decreasing ? h.width - 1 - s : s;
      y = h.y_decreasing ? h.height - 1 - p : p;
    }
    const int row = h.height - 1 - y;
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(h.width) + static_cast<std::size_t>(x);
  }
  /// True when scanline s is image row s, left to right (the standard file): then rows are written contiguously.
  bool standard() const { return h.y_major && h.y_decreasing && !h.x_decreasing; }
};

void store_scanline(const unsigned char* rgbe, int s, int length, const Placement& place,
                    const std::array<float, 3>& scale, float* out) {
  const auto& table = exponent_table();
  const bool contiguous = place.standard();
  float* row = contiguous ? out + place.index(s, 0) * 3 : nullptr;
  for (int p = 0; p < length; ++p) {
    const unsigned char* px = rgbe + p * 4;
    float* dst = contiguous ? row + p * 3 : out + place.index(s, p) * 3;
    const float f = table[px[3]];
    for (int c = 0; c < 3; ++c) {
      // A tiny exposure could push the largest RGBE value past float: clamp, no Inf may leave the decoder.
      const float v = static_cast<float>(px[c]) * f * scale[static_cast<std::size_t>(c)];
      dst[c] = std::isfinite(v) ? v : FLT_MAX;
    }
  }
}

// ---- encoding -------------------------------------------------------------------------------------------------------
//
// A row is converted to four byte planes (R, G, B and E mantissa/exponent bytes, as new-style RLE stores them), then
// each plane is run-length encoded straight into a preallocated buffer. Every row's bytes depend only on that row, so
// rows can be encoded in any order on any number of threads and the file is the same.

/// RGBE of one colour, the general case: mantissas rounded to nearest, as in the description of image_codecs.h.
/// Used for the texels the fast path of rgbe_planes() leaves out: black and tiny values, values near float's largest,
/// and non-finite ones (NaN as 0, +Inf saturates).
void to_rgbe_general(const float* rgb, unsigned char* out) {
  // Negatives and NaN are 0 (NaN fails the comparison); +Inf stays, and saturates below.
  const float r = rgb[0] > 0.0f ? rgb[0] : 0.0f, g = rgb[1] > 0.0f ? rgb[1] : 0.0f, b = rgb[2] > 0.0f ? rgb[2] : 0.0f;
  const float v = std::max({r, g, b});
  if (!(v >= 1e-38f)) {
    std::memset(out, 0, 4);
    return;
  }
  if (std::isinf(v)) {
    out[0] = out[1] = out[2] = out[3] = 255;
    return;
  }
  int e = 0;
  (void)std::frexp(v, &e);  // v = m 2^e, m in [0.5, 1)
  auto mantissas = [&](int exponent, long* m) {
    if (8 - exponent <= 127) {
      // The scale is a float power of two, so r * k is exact; adding 0.5f in float and truncating is the rounding
      // the encoder has always used (and that rgbe_planes() repeats bit for bit).
      const float k = std::ldexp(1.0f, 8 - exponent);
      m[0] = static_cast<long>(r * k + 0.5f), m[1] = static_cast<long>(g * k + 0.5f),
      m[2] = static_cast<long>(b * k + 0.5f);
    } else {
      // v below 2^-120: 2^(8 - e) overflows float, so scale in double (exact, then rounded to nearest once).
      const double k = std::ldexp(1.0, 8 - exponent);
      m[0] = static_cast<long>(r * k + 0.5), m[1] = static_cast<long>(g * k + 0.5),
      m[2] = static_cast<long>(b * k + 0.5);
    }
  };
  long m[3];
  mantissas(e, m);
  if (std::max({m[0], m[1], m[2]}) > 255) mantissas(++e, m);  // rounding carried into the next exponent
  if (e + 128 > 255) {                                        // beyond RGBE's range: saturate
    out[0] = out[1] = out[2] = 255, out[3] = 255;
    return;
  }
  if (e + 128 < 1) {
    std::memset(out, 0, 4);
    return;
  }
  for (int c = 0; c < 3; ++c) out[c] = static_cast<unsigned char>(std::min(m[c], 255L));
  out[3] = static_cast<unsigned char>(e + 128);
}

/// Biased float exponents of the largest component that the fast paths below handle: from 7 (2^-120, below which the
/// scale 2^(8 - e) is no float) to 252 (below 2^126, so that neither the exponent byte nor a rounding carry leaves
/// RGBE's range). Everything else (black included) goes through to_rgbe_general().
constexpr std::uint32_t kFastMinExp = 7, kFastMaxExp = 252;

/// True when to_rgbe_general() must encode the texel: its largest component is outside the fast range (or NaN).
bool needs_general(const float* p) {
  const auto biased = [](float f) { return f > 0.0f ? std::bit_cast<std::uint32_t>(f) >> 23 : 0u; };
  const std::uint32_t ex = std::max({biased(p[0]), biased(p[1]), biased(p[2])});
  return ex < kFastMinExp || ex > kFastMaxExp;
}

/// The fast path of rgbe_planes() for texels [x0, n), one at a time: the same bytes as to_rgbe_general() for texels in
/// the fast range, without frexp or ldexp. The exponent comes from the IEEE bits of the largest component, the scale
/// 2^(8 - e) is built from bits, and the rounding is the same float r * k + 0.5f, truncated, with one more exponent
/// (half the scale) when the largest component rounds to 256. Other texels get bytes to be overwritten; inputs are
/// clamped to [0, FLT_MAX] so that every conversion to int is defined. Returns true if any texel needs the general
/// path.
bool rgbe_fast_scalar(const float* src, std::size_t nc, int x0, int n, unsigned char* const plane[4]) {
  bool any_general = false;
  for (int x = x0; x < n; ++x) {
    const float* p = src + static_cast<std::size_t>(x) * nc;
    const float r = std::min(p[0] > 0.0f ? p[0] : 0.0f, FLT_MAX), g = std::min(p[1] > 0.0f ? p[1] : 0.0f, FLT_MAX),
                b = std::min(p[2] > 0.0f ? p[2] : 0.0f, FLT_MAX);
    const float v = std::max(r, std::max(g, b));
    const std::uint32_t biased = std::bit_cast<std::uint32_t>(v) >> 23;  // v >= 0: no sign bit
    any_general |= biased < kFastMinExp || biased > kFastMaxExp;
    const std::uint32_t ex = std::clamp(biased, kFastMinExp, kFastMaxExp);
    // frexp's exponent is ex - 126; the scale 2^(8 - (ex - 126)) has the biased exponent 127 + 134 - ex.
    float k = std::bit_cast<float>((261u - ex) << 23);
    const int carry = static_cast<int>(v * k + 0.5f) > 255 ? 1 : 0;  // only the largest component can reach 256
    k = carry ? k * 0.5f : k;
    plane[0][x] = static_cast<unsigned char>(static_cast<int>(r * k + 0.5f));
    plane[1][x] = static_cast<unsigned char>(static_cast<int>(g * k + 0.5f));
    plane[2][x] = static_cast<unsigned char>(static_cast<int>(b * k + 0.5f));
    plane[3][x] = static_cast<unsigned char>(static_cast<int>(ex) + 2 + carry);  // e + 128 = ex - 126 + 128
  }
  return any_general;
}

#if defined(__SSE2__)
/// _MM_SHUFFLE with the lanes in reading order: result lane i takes source lane li.
constexpr int lanes(int l0, int l1, int l2, int l3) { return l0 | (l1 << 2) | (l2 << 4) | (l3 << 6); }

/// rgbe_fast_scalar() for packed RGB (stride 3), four texels at a time with SSE2 (part of every x86-64): the same
/// operations in the same float precision, so the same bytes. Returns the first texel not done (n rounded down to 4).
int rgbe_fast_sse2(const float* src, int n, unsigned char* const plane[4], bool& any_general) {
  const __m128 zero = _mm_setzero_ps(), half = _mm_set1_ps(0.5f), largest = _mm_set1_ps(FLT_MAX);
  const __m128 lo = _mm_castsi128_ps(_mm_set1_epi32(static_cast<int>(kFastMinExp << 23)));  // 2^-120
  const __m128 hi = _mm_castsi128_ps(_mm_set1_epi32(static_cast<int>((kFastMaxExp << 23) | 0x7fffff)));
  const __m128i c261 = _mm_set1_epi32(261), c255 = _mm_set1_epi32(255), c2 = _mm_set1_epi32(2);
  int general = 0, x = 0;
  for (; x + 4 <= n; x += 4) {
    const float* p = src + static_cast<std::size_t>(x) * 3;
    // r0 g0 b0 r1 | g1 b1 r2 g2 | b2 r3 g3 b3 -> r0..r3, g0..g3, b0..b3
    const __m128 m0 = _mm_loadu_ps(p), m1 = _mm_loadu_ps(p + 4), m2 = _mm_loadu_ps(p + 8);
    const __m128 r23 = _mm_shuffle_ps(m1, m2, lanes(2, 2, 1, 1));
    const __m128 g01 = _mm_shuffle_ps(m0, m1, lanes(1, 1, 0, 0)), g23 = _mm_shuffle_ps(m1, m2, lanes(3, 3, 2, 2));
    const __m128 b01 = _mm_shuffle_ps(m0, m1, lanes(2, 2, 1, 1)), b23 = _mm_shuffle_ps(m2, m2, lanes(0, 0, 3, 3));
    // max(x, 0) gives 0 for NaN (the second operand wins when one is NaN), then clamp +Inf to FLT_MAX.
    const __m128 r = _mm_min_ps(_mm_max_ps(_mm_shuffle_ps(m0, r23, lanes(0, 3, 0, 2)), zero), largest);
    const __m128 g = _mm_min_ps(_mm_max_ps(_mm_shuffle_ps(g01, g23, lanes(0, 2, 0, 2)), zero), largest);
    const __m128 b = _mm_min_ps(_mm_max_ps(_mm_shuffle_ps(b01, b23, lanes(0, 2, 0, 2)), zero), largest);
    const __m128 v = _mm_max_ps(r, _mm_max_ps(g, b));
    // Clamping v to the fast range clamps its exponent; a texel whose v changed needs the general path.
    const __m128 vc = _mm_min_ps(_mm_max_ps(v, lo), hi);
    general |= _mm_movemask_ps(_mm_cmpneq_ps(v, vc));
    const __m128i ex = _mm_srli_epi32(_mm_castps_si128(vc), 23);
    __m128 k = _mm_castsi128_ps(_mm_slli_epi32(_mm_sub_epi32(c261, ex), 23));
    const __m128i carry = _mm_cmpgt_epi32(_mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(vc, k), half)), c255);  // 0 or -1
    k = _mm_or_ps(_mm_and_ps(_mm_castsi128_ps(carry), _mm_mul_ps(k, half)), _mm_andnot_ps(_mm_castsi128_ps(carry), k));
    const __m128i mr = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(r, k), half));
    const __m128i mg = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(g, k), half));
    const __m128i mb = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(b, k), half));
    const __m128i me = _mm_sub_epi32(_mm_add_epi32(ex, c2), carry);
    // Fast-range values are 0..255: pack to r0..r3 g0..g3 b0..b3 e0..e3.
    alignas(16) unsigned char bytes[16];
    _mm_store_si128(reinterpret_cast<__m128i*>(bytes),
                    _mm_packus_epi16(_mm_packs_epi32(mr, mg), _mm_packs_epi32(mb, me)));
    for (int c = 0; c < 4; ++c) std::memcpy(plane[c] + x, bytes + 4 * c, 4);
  }
  any_general = any_general || general != 0;
  return x;
}
#endif

/// RGBE bytes of `n` texels (stride `nc` floats, the first three read) into the planes R, G, B, E: texel by texel the
/// bytes of to_rgbe_general(), computed by the fast paths and redone by the general one where those do not apply.
void rgbe_planes(const float* src, std::size_t nc, int n, unsigned char* const plane[4]) {
  bool any_general = false;
  int x = 0;
#if defined(__SSE2__)
  if (nc == 3) x = rgbe_fast_sse2(src, n, plane, any_general);
#endif
  any_general = rgbe_fast_scalar(src, nc, x, n, plane) || any_general;
  if (!any_general) return;
  for (x = 0; x < n; ++x) {
    const float* p = src + static_cast<std::size_t>(x) * nc;
    if (!needs_general(p)) continue;
    unsigned char px[4];
    to_rgbe_general(p, px);
    for (int c = 0; c < 4; ++c) plane[c][x] = px[c];
  }
}

/// Most bytes encode_plane() writes for a plane of n bytes. Dumps of L bytes in all cost L plus one count byte per 128
/// bytes or part of them; each run (>= 4 bytes) costs 2 and starts at most one more dump: at most 3 bytes for 4, so
/// the total stays below n + n / 128 + 2.
constexpr std::size_t plane_bound(std::size_t n) { return n + n / 128 + 2; }

constexpr int kMinRun = 4, kMaxRun = 127, kMaxDump = 128;

/// First j >= from with p[j] == p[j + 1] == p[j + 2] == p[j + 3] (j + 3 < n), or n. Since the encoder cuts the plane
/// into maximal runs of equal bytes, this is where the next run of kMinRun or more starts.
int find_run(const unsigned char* p, int from, int n) {
  int j = from;
#if defined(__SSE2__)
  for (; j + 3 + 16 <= n; j += 16) {  // 16 candidate starts, reading p[j .. j + 18]
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + j));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + j + 1));
    const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + j + 2));
    const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + j + 3));
    const int hits = _mm_movemask_epi8(
        _mm_and_si128(_mm_and_si128(_mm_cmpeq_epi8(a, b), _mm_cmpeq_epi8(b, c)), _mm_cmpeq_epi8(c, d)));
    if (hits != 0) return j + std::countr_zero(static_cast<unsigned>(hits));
  }
#endif
  for (; j + 3 < n; ++j)
    if (p[j] == p[j + 1] && p[j] == p[j + 2] && p[j] == p[j + 3]) return j;
  return n;
}

/// Length of the run of bytes equal to p[0], at most `limit` (>= 1).
int run_length(const unsigned char* p, int limit) {
  int len = 1;
#if defined(__SSE2__)
  const __m128i first = _mm_set1_epi8(static_cast<char>(p[0]));
  for (; len + 16 <= limit; len += 16) {  // 16 bytes at a time, reading p[len .. len + 15]
    const __m128i next = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + len));
    const unsigned differ = ~static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(next, first))) & 0xffffu;
    if (differ != 0) return len + std::countr_zero(differ);
  }
#endif
  while (len < limit && p[len] == p[0]) ++len;
  return len;
}

/// Radiance's new-style encoding of one channel plane into `out` (at least plane_bound(n) bytes); returns the end.
/// The plane is cut into runs of equal bytes, 127 at most (a longer run is cut into 127s and the rest); runs of 4 or
/// more are written as runs (count 128 + length, then the byte), everything between them as dumps of at most 128
/// bytes (count, then the bytes).
unsigned char* encode_plane(const unsigned char* plane, int n, unsigned char* out) {
  int i = 0;  // first byte not written yet
  while (i < n) {
    const int run_start = find_run(plane, i, n);
    while (i < run_start) {  // the bytes before the run as dumps
      const int count = std::min(kMaxDump, run_start - i);
      *out++ = static_cast<unsigned char>(count);
      std::memcpy(out, plane + i, static_cast<std::size_t>(count));
      out += count, i += count;
    }
    if (run_start == n) break;
    const int run_len = run_length(plane + run_start, std::min(kMaxRun, n - run_start));
    *out++ = static_cast<unsigned char>(128 + run_len);
    *out++ = plane[run_start];
    i = run_start + run_len;
  }
  return out;
}

/// True when rows of this width are written as new-style RLE scanlines (else flat RGBE).
bool rle_width(int w) { return w >= kMinRle && w <= kMaxRle; }

/// Most bytes one encoded row of width w takes.
std::size_t row_bound(int w) {
  const auto n = static_cast<std::size_t>(w);
  return rle_width(w) ? 4 + 4 * plane_bound(n) : 4 * n;
}

/// Encodes row y to `out` (at least row_bound(width) bytes), with `planes` (4 * width bytes) as scratch; returns the
/// end of the row's bytes.
unsigned char* encode_row(const Image& image, int y, unsigned char* planes, unsigned char* out) {
  const int w = image.width;
  const auto n = static_cast<std::size_t>(w);
  unsigned char* const plane[4] = {planes, planes + n, planes + 2 * n, planes + 3 * n};
  rgbe_planes(image.at(0, y), static_cast<std::size_t>(image.channels), w, plane);
  if (!rle_width(w)) {  // flat scanline: interleaved RGBE
    for (std::size_t x = 0; x < n; ++x)
      for (int c = 0; c < 4; ++c) *out++ = plane[c][x];
    return out;
  }
  *out++ = 2, *out++ = 2, *out++ = static_cast<unsigned char>(w >> 8), *out++ = static_cast<unsigned char>(w & 0xff);
  for (int c = 0; c < 4; ++c) out = encode_plane(plane[c], w, out);
  return out;
}

/// How the rows are cut for encode_radiance(): blocks of rows, each encoded by one task into its own buffer, and bands
/// of blocks, encoded in parallel and then handed to the sink in order. The sizes depend on the width only (never on
/// the thread count), so memory is bounded by one band whatever the image size and core count.
struct RowBlocks {
  int rows_per_block;
  int blocks_per_band;
  explicit RowBlocks(int width) {
    constexpr std::size_t kBlockBytes = std::size_t(256) << 10;  // ~256 KiB of encoded output per block at most
    rows_per_block = static_cast<int>(std::clamp<std::size_t>(kBlockBytes / row_bound(width), 1, 64));
    blocks_per_band = 16;  // enough tasks for the cores to share, few enough to bound memory (~4 MiB)
  }
};

// ---- colour ---------------------------------------------------------------------------------------------------------

using M3 = std::array<double, 9>;

M3 mul(const M3& a, const M3& b) {
  M3 r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) r[i * 3 + j] += a[i * 3 + k] * b[k * 3 + j];
  return r;
}

M3 inverse(const M3& m) {
  const double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7], i = m[8];
  const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  return {(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det,
          (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
          (d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det};
}

std::array<double, 3> mat_vec(const M3& m, const std::array<double, 3>& v) {
  return {m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
          m[6] * v[0] + m[7] * v[1] + m[8] * v[2]};
}

std::array<double, 3> xy_to_xyz(double x, double y) { return {x / y, 1.0, (1.0 - x - y) / y}; }

}  // namespace

bool looks_like_radiance(Bytes bytes) { return bytes.size() >= 2 && bytes[0] == '#' && bytes[1] == '?'; }

RadianceHeader parse_radiance_header(Bytes bytes, const std::string& name) {
  if (!looks_like_radiance(bytes)) fail(name, "not a Radiance file (no \"#?\" first line)");
  RadianceHeader h;
  std::size_t pos = 0;
  const std::size_t limit = std::min(bytes.size(), kRadianceMaxHeaderBytes);
  auto next_line = [&](std::string& line) {
    const std::size_t start = pos;
    while (pos < limit && bytes[pos] != '\n') ++pos;
    if (pos >= limit) {
      if (limit < bytes.size()) fail(name, "Radiance header longer than " + std::to_string(limit >> 20) + " MiB");
      fail(name, "cannot read: truncated Radiance header");
    }
    line.assign(reinterpret_cast<const char*>(bytes.data()) + start, pos - start);
    ++pos;
  };
  std::string line;
  next_line(line);  // "#?RADIANCE", "#?RGBE", ...
  bool has_format = false;
  for (;;) {
    next_line(line);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) break;
    const std::size_t eq = line.find('=');
    if (line[0] == '#' || eq == std::string::npos) continue;  // comments, commands of the history
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    if (key == "FORMAT") {
      if (value == "32-bit_rle_rgbe")
        h.xyze = false;
      else if (value == "32-bit_rle_xyze")
        h.xyze = true;
      else
        fail(name, "unsupported Radiance FORMAT '" + value.substr(0, 64) +
                       "' (envkit reads 32-bit_rle_rgbe and 32-bit_rle_xyze)");
      has_format = true;
    } else if (key == "EXPOSURE") {
      double e = 0;
      if (!parse_positive(value, 1, &e)) fail(name, "bad EXPOSURE line '" + value.substr(0, 64) + "'");
      h.exposure *= e;
    } else if (key == "COLORCORR") {
      double c[3];
      if (!parse_positive(value, 3, c)) fail(name, "bad COLORCORR line '" + value.substr(0, 64) + "'");
      for (int k = 0; k < 3; ++k) h.colorcorr[static_cast<std::size_t>(k)] *= c[k];
    } else {
      if (key == "PRIMARIES") h.primaries = value;
      if (!key.empty()) h.variables.emplace_back(key, value);
    }
  }
  (void)has_format;  // files without FORMAT are RGBE (Radiance's own default)
  if (!(std::isfinite(h.exposure) && h.exposure > 0) ||
      !std::all_of(h.colorcorr.begin(), h.colorcorr.end(), [](double c) { return std::isfinite(c) && c > 0; }))
    fail(name, "EXPOSURE/COLORCORR product out of range");
  next_line(line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (!parse_resolution(line, h))
    fail(name, "bad Radiance resolution string '" + line.substr(0, 64) +
                   "' (expected e.g. '-Y 512 +X 1024': -/+Y then -/+X, or -/+X "
                   "then -/+Y)");
  h.data_offset = pos;
  return h;
}

Image decode_radiance(Bytes bytes, const RadianceHeader& h, const std::string& name) {
  Image image(h.width, h.height, 3);
  image.channel_names = h.xyze ? std::vector<std::string>{"X", "Y", "Z"} : std::vector<std::string>{"R", "G", "B"};
  const int scans = h.scanline_count(), length = h.scanline_length();
  const std::array<float, 3> scale = {static_cast<float>(1.0 / (h.exposure * h.colorcorr[0])),
                                      static_cast<float>(1.0 / (h.exposure * h.colorcorr[1])),
                                      static_cast<float>(1.0 / (h.exposure * h.colorcorr[2]))};
  const Placement place{h};
  const unsigned char* const end = bytes.data() + bytes.size();
  const unsigned char* p = bytes.data() + std::min(h.data_offset, bytes.size());

  // Serial pass: new-style scanlines are checked and skipped (their starts kept for the parallel pass), others decoded
  // here, since their length is only known by decoding them.
  constexpr std::size_t kDecoded = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> starts(static_cast<std::size_t>(scans), kDecoded);
  std::vector<unsigned char> scratch(static_cast<std::size_t>(length) * 4);
  bool any_new = false;
  for (int s = 0; s < scans; ++s) {
    if (p >= end) bad_scanline(name, s, "data ends before the scanline");
    if (is_new_style(p, end, length)) {
      starts[static_cast<std::size_t>(s)] = static_cast<std::size_t>(p - bytes.data());
      p = new_style<false>(p, end, length, nullptr, name, s);
      any_new = true;
    } else {
      p = old_style(p, end, length, scratch.data(), name, s);
      store_scanline(scratch.data(), s, length, place, scale, image.pixels.data());
    }
  }
  if (!any_new) return image;
  // Every run was checked above: this pass cannot fail.
  tbb::parallel_for(tbb::blocked_range<int>(0, scans, 16), [&](const tbb::blocked_range<int>& r) {
    std::vector<unsigned char> rgbe(static_cast<std::size_t>(length) * 4);
    for (int s = r.begin(); s != r.end(); ++s) {
      const std::size_t start = starts[static_cast<std::size_t>(s)];
      if (start == kDecoded) continue;
      new_style<true>(bytes.data() + start, end, length, rgbe.data(), name, s);
      store_scanline(rgbe.data(), s, length, place, scale, image.pixels.data());
    }
  });
  return image;
}

std::array<double, 9> radiance_xyz_to_rec709() {
  // Linear Rec.709 RGB -> XYZ for D65 white, from the primaries (ITU-R BT.709).
  const auto r = xy_to_xyz(0.64, 0.33), g = xy_to_xyz(0.30, 0.60), b = xy_to_xyz(0.15, 0.06);
  const auto d65 = xy_to_xyz(0.3127, 0.3290);
  const M3 primaries = {r[0], g[0], b[0], r[1], g[1], b[1], r[2], g[2], b[2]};
  const auto s = mat_vec(inverse(primaries), d65);
  const M3 rgb_to_xyz = {r[0] * s[0], g[0] * s[1], b[0] * s[2], r[1] * s[0], g[1] * s[1],
                         b[1] * s[2], r[2] * s[0], g[2] * s[1], b[2] * s[2]};
  // Bradford adaptation from Radiance's equal-energy white (1, 1, 1) to D65.
  const M3 bradford = {0.8951, 0.2664, -0.1614, -0.7502, 1.7135, 0.0367, 0.0389, -0.0685, 1.0296};
  const auto cone_e = mat_vec(bradford, {1.0, 1.0, 1.0}), cone_d65 = mat_vec(bradford, d65);
  const M3 gain = {cone_d65[0] / cone_e[0], 0, 0, 0, cone_d65[1] / cone_e[1], 0, 0, 0, cone_d65[2] / cone_e[2]};
  const M3 adapt = mul(inverse(bradford), mul(gain, bradford));
  return mul(inverse(rgb_to_xyz), adapt);
}

void encode_radiance(const Image& image, const std::map<std::string, std::string>& variables,
                     const std::function<void(const unsigned char*, std::size_t)>& sink) {
  std::string header = "#?RADIANCE\n";
  for (const auto& [key, value] : variables) {
    if (key.empty() || key == "FORMAT" || key == "EXPOSURE" || key == "COLORCORR") continue;
    std::string line = key + "=" + value;
    std::replace(line.begin(), line.end(), '\n', ' ');
    std::replace(line.begin(), line.end(), '\r', ' ');
    header += line + "\n";
  }
  header +=
      "FORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(image.height) + " +X " + std::to_string(image.width) + "\n";
  sink(reinterpret_cast<const unsigned char*>(header.data()), header.size());
  if (image.height <= 0 || image.width <= 0) return;
  const RowBlocks cut(image.width);
  const std::size_t block_bytes = row_bound(image.width) * static_cast<std::size_t>(cut.rows_per_block);
  const int blocks = (image.height + cut.rows_per_block - 1) / cut.rows_per_block;
  std::vector<std::vector<unsigned char>> buffers(static_cast<std::size_t>(std::min(cut.blocks_per_band, blocks)));
  std::vector<std::size_t> sizes(buffers.size());
  for (int band = 0; band < blocks; band += cut.blocks_per_band) {
    const int band_end = std::min(blocks, band + cut.blocks_per_band);
    tbb::parallel_for(tbb::blocked_range<int>(band, band_end, 1), [&](const tbb::blocked_range<int>& r) {
      std::vector<unsigned char> planes(static_cast<std::size_t>(image.width) * 4);
      for (int b = r.begin(); b != r.end(); ++b) {
        std::vector<unsigned char>& buffer = buffers[static_cast<std::size_t>(b - band)];
        buffer.resize(block_bytes);  // allocated once, by the first band
        unsigned char* out = buffer.data();
        const int y1 = std::min(image.height, (b + 1) * cut.rows_per_block);
        for (int y = b * cut.rows_per_block; y < y1; ++y) out = encode_row(image, y, planes.data(), out);
        sizes[static_cast<std::size_t>(b - band)] = static_cast<std::size_t>(out - buffer.data());
      }
    });
    for (int b = band; b < band_end; ++b)
      sink(buffers[static_cast<std::size_t>(b - band)].data(), sizes[static_cast<std::size_t>(b - band)]);
  }
}

std::vector<unsigned char> encode_radiance(const Image& image, const std::map<std::string, std::string>& variables) {
  std::vector<unsigned char> out;
  encode_radiance(image, variables, [&](const unsigned char* p, std::size_t n) { out.insert(out.end(), p, p + n); });
  return out;
}

}  // namespace envkit
