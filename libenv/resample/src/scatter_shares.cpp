// The area scatter's shares (scatter_shares.h): the geometry's tables, the per-axis overlap loop and the shares on
// AVX2 lanes.
#include "scatter_shares.h"

#include <envkit/core/simd/simd_level.h>
#include <envkit/maps/latlong.h>
#include <tbb/parallel_for.h>

#include <cstdlib>

// Last: its target attribute applies to the functions that use it.
#include <envkit/core/simd/avx2_target.h>

namespace envkit::detail {

RowScales latlong_row_scales(const Parameterization& dst) {
  RowScales r;
  const LatLongMap* ll = dst.latlong_geometry();
  if (!ll) return r;
  const int H = dst.height();
  r.x.resize(H);
  r.y.resize(H);
  for (int j = 0; j < H; ++j) {
    const Vec2 a = ll->domain_from_image(Vec2(0.0, j)), b = ll->domain_from_image(Vec2(1.0, j + 1.0));
    const double v = std::clamp(0.5 * (a.y + b.y), 0.0, 1.0);
    r.x[j] = 1.0 / std::max(LatLongMap::kRadiansPerU * (b.x - a.x) * std::sin(LatLongMap::polar_angle(v)), 1e-300);
    r.y[j] = 1.0 / (LatLongMap::kRadiansPerV * (b.y - a.y));
  }
  return r;
}

ScatterGeometry::ScatterGeometry(const Parameterization& s, const Parameterization& d, const SolidAngleTable& s_omega,
                                 const SolidAngleTable& d_omega, const Mat3& dst_to_src)
    : src(s),
      dst(d),
      src_omega(s_omega),
      src_to_dst(transposed(dst_to_src)),
      rotate(!is_identity(src_to_dst)),
      directions(s),
      row_scales(latlong_row_scales(d)),
      omega_per_row(s.latlong_geometry() != nullptr && s.width() > 2),
      W(s.width()),
      DW(d.width()),
      DH(d.height()),
      rows(LatLongRowsInCube::make(s, d, src_to_dst, rotate)) {
  if (!row_scales.x.empty()) return;
  inverse_side.resize(std::size_t(DW) * std::size_t(DH));
  tbb::parallel_for(0, DH, [&](int j) {
    for (int i = 0; i < DW; ++i) {
      const double omega = d_omega(i, j);
      inverse_side[std::size_t(j) * DW + i] = omega > 0.0 ? static_cast<float>(1.0 / std::sqrt(omega)) : 0.0f;
    }
  });
}

ShareLister::ShareLister(const ScatterGeometry& g, bool lanes)
    : g_(g),
      lanes_(false),
      list_(kContributionCapacity),
      landed_(std::make_unique<Landed>()),
      row_x_(g.rows ? kBatchTexels : 0),
      row_y_(row_x_.size()) {
#if defined(ENVKIT_AVX2)
  lanes_ = lanes && g.row_scales.x.empty();
  if (lanes_) shares_ = std::make_unique<Shares>();
#else
  (void)lanes;
#endif
}

void ShareLister::overlap_shares(int k, int& n) {
  Contribution* list = list_.data();
  const Landed& l = *landed_;
  const double px = l.x[k], py = l.y[k], omega_s = l.omega[k];
  const int ti = l.ti[k], tj = l.tj[k];
  double width, height;
  g_.square(std::sqrt(omega_s), ti, tj, width, height);
  const double x0 = px - 0.5 * width, y0 = py - 0.5 * height;
  if (width > 1.0 || height > 1.0) [[unlikely]] {
    double fx[kMaxSplatCellsPerAxis], fy[kMaxSplatCellsPerAxis];
    int nx, ny;
    const int cx = overlaps(x0, x0 + width, fx, nx), cy = overlaps(y0, y0 + height, fy, ny);
    for (int b = 0; b < ny; ++b)
      for (int a = 0; a < nx; ++a)
        if (fx[a] * fy[b] > 0.0) list[n++] = {cx + a, cy + b, ti, tj, omega_s * fx[a] * fy[b], l.pixel[k]};
    return;
  }
  // As overlaps(): the fraction of [x0, x0 + width) in the cell holding x0, the rest in the next cell.
  const double cx = std::floor(x0), cy = std::floor(y0);
  const double x1 = x0 + width, y1 = y0 + height;
  const double fx0 = x1 <= cx + 1.0 ? 1.0 : (cx + 1.0 - x0) * (1.0 / (x1 - x0));
  const double fy0 = y1 <= cy + 1.0 ? 1.0 : (cy + 1.0 - y0) * (1.0 / (y1 - y0));
  const double fx1 = 1.0 - fx0, fy1 = 1.0 - fy0;
  const int ci = static_cast<int>(cx), cj = static_cast<int>(cy);
  const float* px_ = l.pixel[k];
  list[n] = {ci, cj, ti, tj, omega_s * fx0 * fy0, px_};
  n += 1;
  list[n] = {ci + 1, cj, ti, tj, omega_s * fx1 * fy0, px_};
  n += fx1 * fy0 > 0.0;
  list[n] = {ci, cj + 1, ti, tj, omega_s * fx0 * fy1, px_};
  n += fx0 * fy1 > 0.0;
  list[n] = {ci + 1, cj + 1, ti, tj, omega_s * fx1 * fy1, px_};
  n += fx1 * fy1 > 0.0;
}

void nearest_source_texel(const MapRef& s, const Parameterization& dst, const Mat3& dst_to_src,
                          const std::vector<std::size_t>& hot, int ti, int tj, float* px) {
  const Image& img = s.image;
  const int C = img.channels, W = img.width, H = img.height;
  Vec3 d;
  Vec2 q;
  if (!dst.covered_point(ti, tj, q) || !dst.to_direction(q, d)) return;
  const Vec2 p = s.param.to_image(apply(dst_to_src, d));
  const std::size_t index = std::size_t(std::clamp(static_cast<int>(p.y), 0, H - 1)) * W +
                            std::size_t(std::clamp(static_cast<int>(p.x), 0, W - 1));
  if (std::binary_search(hot.begin(), hot.end(), index)) return;
  for (int c = 0; c < C; ++c) px[c] = img.pixels[index * C + c];
}

#if defined(ENVKIT_AVX2)
// The scalar code's operations in its order, each exact in IEEE double (sqrt, division, floor, min and products; the
// attribute enables AVX2 alone, so nothing is fused into an FMA), so the same doubles bit for bit.
ENVKIT_AVX2 void shares_avx2(const Landed& l, int m, const float* inverse_side, int DW, Shares& s) {
  const __m256d zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1.0);
  const __m256d cap = _mm256_set1_pd(kMaxSideInTexels);
  const __m128i width = _mm_set1_epi32(DW);
  for (int k = 0; k < m; k += kBatchLanes) {
    const __m128i ti = _mm_load_si128(reinterpret_cast<const __m128i*>(l.ti + k));
    const __m128i tj = _mm_load_si128(reinterpret_cast<const __m128i*>(l.tj + k));
    // ScatterGeometry::square: inverse > 0 ? std::min(sqrt(omega) * inverse, cap) : 1, with std::min(a, cap) being
    // cap < a ? cap : a.
    const __m256d inverse =
        _mm256_cvtps_pd(_mm_i32gather_ps(inverse_side, _mm_add_epi32(_mm_mullo_epi32(tj, width), ti), 4));
    const __m256d omega = _mm256_load_pd(l.omega + k);
    const __m256d product = _mm256_mul_pd(_mm256_sqrt_pd(omega), inverse);
    const __m256d capped = _mm256_blendv_pd(product, cap, _mm256_cmp_pd(cap, product, _CMP_LT_OQ));
    const __m256d side = _mm256_blendv_pd(one, capped, _mm256_cmp_pd(inverse, zero, _CMP_GT_OQ));
    const __m256d x0 = _mm256_sub_pd(_mm256_load_pd(l.x + k), _mm256_mul_pd(half, side));
    const __m256d y0 = _mm256_sub_pd(_mm256_load_pd(l.y + k), _mm256_mul_pd(half, side));
    const __m256d cx = _mm256_floor_pd(x0), cy = _mm256_floor_pd(y0);
    const __m256d x1 = _mm256_add_pd(x0, side), y1 = _mm256_add_pd(y0, side);
    const __m256d cx1 = _mm256_add_pd(cx, one), cy1 = _mm256_add_pd(cy, one);
    const __m256d fx0 =
        _mm256_blendv_pd(_mm256_mul_pd(_mm256_sub_pd(cx1, x0), _mm256_div_pd(one, _mm256_sub_pd(x1, x0))), one,
                         _mm256_cmp_pd(x1, cx1, _CMP_LE_OQ));
    const __m256d fy0 =
        _mm256_blendv_pd(_mm256_mul_pd(_mm256_sub_pd(cy1, y0), _mm256_div_pd(one, _mm256_sub_pd(y1, y0))), one,
                         _mm256_cmp_pd(y1, cy1, _CMP_LE_OQ));
    const __m256d fx1 = _mm256_sub_pd(one, fx0), fy1 = _mm256_sub_pd(one, fy0);
    _mm256_store_pd(s.w00 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx0), fy0));
    _mm256_store_pd(s.w10 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx1), fy0));
    _mm256_store_pd(s.w01 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx0), fy1));
    _mm256_store_pd(s.w11 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx1), fy1));
    _mm_store_si128(reinterpret_cast<__m128i*>(s.ci + k), _mm256_cvttpd_epi32(cx));
    _mm_store_si128(reinterpret_cast<__m128i*>(s.cj + k), _mm256_cvttpd_epi32(cy));
    const int word = k / kBatchLanes;
    s.big[word] = static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(side, one, _CMP_GT_OQ)));
    s.f10[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx1, fy0), zero, _CMP_GT_OQ)));
    s.f01[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx0, fy1), zero, _CMP_GT_OQ)));
    s.f11[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx1, fy1), zero, _CMP_GT_OQ)));
  }
}
#else
void shares_avx2(const Landed&, int, const float*, int, Shares&) { std::abort(); }  // never called: lanes are off
#endif

std::vector<float> hot_weight_copies(const Image& img, const std::size_t* begin, const std::size_t* end) {
  const int C = img.channels;
  std::vector<float> copies(std::size_t(end - begin) * std::size_t(C), 0.0f);
  if (img.alpha_channel >= 0)
    for (const std::size_t* h = begin; h != end; ++h)
      copies[std::size_t(h - begin) * C + img.alpha_channel] = img.pixels[*h * C + img.alpha_channel];
  return copies;
}

}  // namespace envkit::detail
