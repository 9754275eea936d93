#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/sampling/distribution_refined.h>
#include <envkit/sampling/env_sampling.h>

#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace envkit {

const char* method_name(SamplingMethod method) {
  switch (method) {
    case SamplingMethod::Cdf:
      return "cdf";
    case SamplingMethod::Alias:
      return "alias";
    case SamplingMethod::Hierarchical:
      return "hierarchical";
  }
  return "?";
}

SamplingMethod parse_method(const std::string& name) {
  if (name == "cdf") return SamplingMethod::Cdf;
  if (name == "alias") return SamplingMethod::Alias;
  if (name == "hierarchical" || name == "pyramid") return SamplingMethod::Hierarchical;
  throw Error("unknown sampling method '" + name + "' (expected cdf, alias or hierarchical)");
}

namespace {

/// Lat-long row of a unit direction from its horizontal length hypot(x, z) and its y: theta = atan2(h, y).
int latlong_row(double horizontal, double y, int height) {
  return std::clamp(int(LatLongMap::v_of_polar_angle(std::atan2(horizontal, y)) * height), 0, height - 1);
}

/// atan2(y, x) within about 1e-5 rad (a rational-free odd polynomial on [0, 1] and the octant symmetries): a
/// guess that texel_of() corrects against exact texel edges, so its error costs steps, never a wrong texel.
double rough_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double big = std::max(ax, ay);
  const double a = big > 0.0 ? std::min(ax, ay) / big : 0.0, s = a * a;
  double r = ((-0.0464964749 * s + 0.15931422) * s - 0.327622764) * s * a + a;
  if (ay > ax) r = 0.5 * kPi - r;
  if (x < 0.0) r = kPi - r;
  return y < 0.0 ? -r : r;
}

bool finite_nonzero(const Vec3& d) {
  const double n2 = d.length2();
  return std::isfinite(n2) && n2 > 0.0;
}

/// The longitude table has at least this many steps (each 2 pi / N wide, N >= kMinLongitudeSteps): the angle d
/// inside a step is then at most 2 pi / 2048 = 3.1e-3, where sin d = d - d^3/6 + d^5/120 and
/// cos d = 1 - d^2/2 + d^4/24 are exact to 1e-18 (the next terms, d^7/5040 and d^6/720), far below an ulp.
constexpr int kMinLongitudeSteps = 2048;

/// The HEALPix map of a W x H bake grid; throws Error unless W x H is 4 N_side x 3 N_side.
std::shared_ptr<const HealpixMap> make_healpix_grid(int width, int height) {
  if (width % 4 != 0 || std::int64_t(width) * 3 != std::int64_t(height) * 4)
    throw Error("spherical distribution: a HEALPix grid is 4 N_side x 3 N_side, got " + std::to_string(width) + "x" +
                std::to_string(height));
  return std::make_shared<const HealpixMap>(width / 4);
}

/// Direction at continuous image position (X, Y) of a HEALPix grid. Inside a texel the face coordinates are linear
/// in the position and the HEALPix projection is equal-area in them, so a uniform position is uniform in solid
/// angle. Every texel of the layout holds data; a miss would be a bug, answered with +Y rather than NaN.
Vec3 healpix_direction(const HealpixMap& map, double X, double Y) {
  Vec3 d(0.0, 1.0, 0.0);
  if (!map.to_direction(Vec2(X, Y), d) || !finite_nonzero(d)) return Vec3(0.0, 1.0, 0.0);
  return d;
}

}  // namespace

SphericalDistribution::RowBand SphericalDistribution::row_band(int j, int height) {
  const double theta0 = LatLongMap::polar_angle(double(j) / height);
  const double theta1 = LatLongMap::polar_angle(double(j + 1) / height);
  RowBand band;
  band.span = LatLongMap::band_height(theta0, theta1);
  const bool north = 2 * j + 1 <= height;  // the row's centre is at or above the equator
  band.g0 = north ? 0.0 : 1.0;
  band.gs = north ? 1.0 : -1.0;
  if (north) {
    const double s = std::sin(0.5 * theta0);
    band.start = 2.0 * s * s;
  } else {
    const double c = std::cos(0.5 * theta1);
    band.start = 2.0 * c * c;
  }
  return band;
}

SphericalDistribution::SphericalDistribution(Kind grid, std::shared_ptr<const Distribution2D> distribution)
    : grid_(grid), distribution_(std::move(distribution)) {
  if (!distribution_) throw Error("spherical distribution: null distribution");
  if (grid_ != Kind::LatLong && grid_ != Kind::Octahedral && grid_ != Kind::HEALPix)
    throw Error(std::string("spherical distribution: unsupported grid '") + kind_name(grid_) +
                "' (expected latlong, octahedral or healpix)");
  if (grid_ == Kind::Octahedral && width() != height())
    throw Error("spherical distribution: an octahedral grid must be square, got " + std::to_string(width()) + "x" +
                std::to_string(height()));
  geometry_ = make_geometry(grid_, width(), height());
  g_ = geometry_.get();
  choose_sampler();
}

SphericalDistribution::SphericalDistribution(const SphericalDistribution& same_grid,
                                             std::shared_ptr<const Distribution2D> distribution)
    : grid_(same_grid.grid_),
      distribution_(std::move(distribution)),
      geometry_(same_grid.geometry_),
      g_(geometry_.get()) {
  if (!distribution_) throw Error("spherical distribution: null distribution");
  if (width() != same_grid.width() || height() != same_grid.height())
    throw Error("spherical distribution: a " + std::to_string(width()) + "x" + std::to_string(height()) +
                " distribution on a " + std::to_string(same_grid.width()) + "x" + std::to_string(same_grid.height()) +
                " grid");
  choose_sampler();
}

std::shared_ptr<const SphericalDistribution::Geometry> SphericalDistribution::make_geometry(Kind grid, int width,
                                                                                            int height) {
  auto geometry = std::make_shared<Geometry>();
  Geometry& G = *geometry;
  const double W = width, H = height;
  G.equal_area_pdf_factor = 1.0 / (W * H * (kFourPi / (W * H)));
  if (grid == Kind::HEALPix) {
    G.healpix = make_healpix_grid(width, height);
    G.healpix_margin = std::min(0.25, G.healpix->to_image_tolerance());
    G.equal_area_pdf_factor = 1.0 / (W * H * G.healpix->pixel_solid_angle());
  }
  if (grid == Kind::LatLong) {
    G.rows.resize(std::size_t(height));
    for (int y = 0; y < height; ++y) {
      RowBand& band = G.rows[std::size_t(y)];
      band = row_band(y, height);
      band.pdf_factor = 1.0 / (W * H * ((kTwoPi / W) * band.span));
    }
    G.longitude_substeps = (kMinLongitudeSteps + width - 1) / width;
    const std::size_t steps = std::size_t(width) * std::size_t(G.longitude_substeps);
    const double step = kTwoPi / double(steps), step2 = step * step;
    G.sin_poly[0] = step;
    G.sin_poly[1] = -step * step2 / 6.0;
    G.sin_poly[2] = step * step2 * step2 / 120.0;
    G.cos_poly[0] = -step2 / 2.0;
    G.cos_poly[1] = step2 * step2 / 24.0;
    G.longitudes.resize(steps + 1);
    for (std::size_t k = 0; k <= steps; ++k) {
      const double a = kTwoPi * (double(k) / double(steps));
      G.longitudes[k] = {std::sin(a), -std::cos(a)};
    }
    G.row_edge_cos.resize(std::size_t(height) + 1);
    for (int y = 0; y <= height; ++y)
      G.row_edge_cos[std::size_t(y)] = std::cos(LatLongMap::polar_angle(double(y) / height));
    G.row_edge_cos.front() = 1.0;
    G.row_edge_cos.back() = -1.0;
  }
  return geometry;
}

void SphericalDistribution::choose_sampler() {
  // Lat-long grids with a built-in distribution get a sampler with its texel choice (pick(): the classes are
  // final, so it is what their sample_texel() returns) and the direction inlined, without a virtual call.
  const BuiltinDistribution builtin = builtin_ = distribution_->builtin();
  if (grid_ == Kind::LatLong) {
    const auto choose = [&]<bool kOneStep>() {
      switch (builtin) {
        case BuiltinDistribution::Cdf:
          sample_ = &sample_latlong<CdfDistribution2D, kOneStep>;
          break;
        case BuiltinDistribution::Alias:
          sample_ = &sample_latlong<AliasDistribution2D, kOneStep>;
          break;
        case BuiltinDistribution::Hierarchical:
          sample_ = &sample_latlong<HierarchicalDistribution2D, kOneStep>;
          break;
        case BuiltinDistribution::Refined:
          sample_ = &sample_latlong<RefinedDistribution2D, kOneStep>;
          break;
        case BuiltinDistribution::Sparse:
        case BuiltinDistribution::Other:
          break;  // sample_general
      }
    };
    if (g_->longitude_substeps == 1)
      choose.template operator()<true>();
    else
      choose.template operator()<false>();
  }
}

double SphericalDistribution::texel_solid_angle(int x, int y) const {
  (void)x;
  const double W = width(), H = height();
  if (grid_ == Kind::HEALPix) return g_->healpix->pixel_solid_angle();
  if (grid_ == Kind::Octahedral) return kFourPi / (W * H);
  return (kTwoPi / W) * g_->rows[std::size_t(std::clamp(y, 0, height() - 1))].span;
}

template <bool kOneStep>
[[gnu::always_inline]] inline Vec3 SphericalDistribution::latlong_direction(const RowBand& band, int x, double fx,
                                                                            double fy) const {
  // Uniform in solid angle inside the row: cos theta linear in fy. from_pole is in [0, 2): every term is >= 0, and
  // it stays within rounding of the row's far edge, 1 - cos theta1 <= 1 + sin(pi / 2H) (north) or
  // 1 + cos theta0 < that (south): at most 1.5 for H >= 2. A single row (H = 1) has start 0 and span exactly 2,
  // so from_pole = 2 fy < 2. Hence from_pole (2 - from_pole) >= 0 and the square root needs no check (the SSE2
  // square root also skips the errno path of std::sqrt).
  const double from_pole = band.start + (band.g0 + band.gs * fy) * band.span;
  const double sin2 = from_pole * (2.0 - from_pole);
#if defined(__SSE2__)
  const double sin_theta = _mm_cvtsd_f64(_mm_sqrt_pd(_mm_set1_pd(sin2)));
#else
  const double sin_theta = std::sqrt(sin2);
#endif
  const double cos_theta = band.gs * (1.0 - from_pole);
  // Longitude lon = pi - a, a = 2 pi (x + fx) / W, linear in fx: a = a_k + d with a_k from the table and d inside
  // one step (see kMinLongitudeSteps), sin a and cos a by angle addition. No trigonometric call per sample.
  std::size_t k = std::size_t(x);
  double f = fx;
  if (!kOneStep && g_->longitude_substeps != 1) {
    const double t = fx * g_->longitude_substeps;  // < g_->longitude_substeps: fx <= 1 - 2^-24
    const int q = static_cast<int>(t);
    k = k * std::size_t(g_->longitude_substeps) + std::size_t(q);
    f = t - q;
  }
  // d = f x step: sin d = d - d^3/6 + d^5/120, cos d = 1 - d^2/2 + d^4/24 as polynomials in f.
  const double f2 = f * f;
  const double sin_d = f * (g_->sin_poly[0] + f2 * (g_->sin_poly[1] + f2 * g_->sin_poly[2]));
  const double cos_d = 1.0 + f2 * (g_->cos_poly[0] + f2 * g_->cos_poly[1]);
  // lon = pi - a: sin lon = sin a, cos lon = -cos a (the table holds -cos a_k).
  const Longitude& l = g_->longitudes[k];
  const double sin_lon = l.sin_a * cos_d - l.minus_cos_a * sin_d;
  const double cos_lon = l.minus_cos_a * cos_d + l.sin_a * sin_d;
  return Vec3(sin_lon * sin_theta, cos_theta, cos_lon * sin_theta);
}

Vec3 SphericalDistribution::direction_in_texel(int x, int y, double fx, double fy) const {
  // A public entry: out-of-range or NaN arguments are clamped (the longitude table and the row bounds assume them
  // in range). The samplers use latlong_direction directly with values already in range.
  x = std::clamp(x, 0, width() - 1);
  y = std::clamp(y, 0, height() - 1);
  fx = sampling::clamp_offset(fx);
  fy = sampling::clamp_offset(fy);
  const double W = width();
  if (grid_ == Kind::HEALPix) {
    // A direction within the margin of an edge could be located in the neighbour (another pdf and radiance than
    // the sample reports); radiance and pdf are constant inside the texel, so moving those few offsets onto the
    // margin (about 2e-9 rad) changes them for no sample.
    const double lo = g_->healpix_margin, hi = 1.0 - g_->healpix_margin;
    return healpix_direction(*g_->healpix, x + std::clamp(fx, lo, hi), y + std::clamp(fy, lo, hi));
  }
  if (grid_ == Kind::Octahedral) return OctahedralMap::direction_from_unit(Vec2((x + fx) / W, (y + fy) / W));
  return latlong_direction<false>(g_->rows[std::size_t(y)], x, fx, fy);
}

void SphericalDistribution::locate(const Vec3& direction, int& x, int& y, double& fx, double& fy) const {
  const int W = width(), H = height();
  Vec3 d = finite_nonzero(direction) ? direction.normalized() : Vec3(0.0, 1.0, 0.0);
  if (grid_ != Kind::LatLong) {
    const Vec2 p =
        grid_ == Kind::HEALPix ? g_->healpix->to_image(d) : OctahedralMap::unit_from_direction(d) * Vec2(W, H);
    x = std::clamp(int(std::floor(p.x)), 0, W - 1);
    y = std::clamp(int(std::floor(p.y)), 0, H - 1);
    fx = std::clamp(p.x - x, 0.0, 1.0);
    fy = std::clamp(p.y - y, 0.0, 1.0);
    return;
  }
  const double horizontal = std::hypot(d.x, d.z);
  const double u = LatLongMap::u_from_direction(d, horizontal);
  x = std::clamp(int(u * W), 0, W - 1);
  fx = std::clamp(u * W - x, 0.0, 1.0);
  y = latlong_row(horizontal, d.y, H);
  const RowBand& band = g_->rows[std::size_t(y)];
  const bool north = band.north();
  // Distance from the nearer pole, 1 -+ cos theta, without cancellation: h^2 / (1 +- cos theta).
  const double from_pole = north ? (d.y > 0.0 ? horizontal * horizontal / (1.0 + d.y) : 1.0 - d.y)
                                 : (d.y < 0.0 ? horizontal * horizontal / (1.0 - d.y) : 1.0 + d.y);
  const double t = (from_pole - band.start) / band.span;
  fy = std::clamp(north ? t : 1.0 - t, 0.0, 1.0);
}

void SphericalDistribution::texel_of(const Vec3& direction, int& x, int& y) const {
  if (grid_ != Kind::LatLong) {
    double fx = 0.0, fy = 0.0;
    locate(direction, x, y, fx, fy);
    return;
  }
  // locate() without the offsets inside the texel: radiance lookups and pdf() need only the texel.
  const Vec3 d = finite_nonzero(direction) ? direction.normalized() : Vec3(0.0, 1.0, 0.0);
  const double horizontal = std::sqrt(d.x * d.x + d.z * d.z);
  const int W = width(), H = height();
  // Row: theta in [theta_y, theta_y+1) <=> edge_cos[y] >= cos theta > edge_cos[y + 1].
  y = std::clamp(int(LatLongMap::v_of_polar_angle(rough_atan2(horizontal, d.y)) * H), 0, H - 1);
  while (y > 0 && d.y > g_->row_edge_cos[std::size_t(y)]) --y;
  while (y < H - 1 && d.y <= g_->row_edge_cos[std::size_t(y) + 1]) ++y;
  // Column: a = pi - longitude in [a_x, a_x+1), a_k = 2 pi k / W. Near a = 0 (the seam, where the guess may fall on
  // the other side) and at the poles (no longitude) the exact formula decides.
  const double a = kPi - rough_atan2(d.x, d.z);
  constexpr double kSeam = 1e-3;
  if (horizontal == 0.0 || a < kSeam || a > kTwoPi - kSeam) {
    x = std::clamp(int(LatLongMap::u_from_direction(d, horizontal) * W), 0, W - 1);
    return;
  }
  // a >= a_k <=> sin(a - a_k) >= 0 (|a - a_k| < pi here), sin(a - a_k) h = d.x cos a_k + d.z sin a_k.
  const auto at_or_after = [&](int k) {
    const Longitude& edge = g_->longitudes[std::size_t(k) * std::size_t(g_->longitude_substeps)];
    return d.z * edge.sin_a - d.x * edge.minus_cos_a >= 0.0;
  };
  x = std::clamp(int(a * (W / kTwoPi)), 0, W - 1);
  while (x > 0 && !at_or_after(x)) --x;
  while (x < W - 1 && at_or_after(x + 1)) ++x;
}

template <class D, bool kOneStep>
DirectionSample SphericalDistribution::sample_latlong(const SphericalDistribution& s, const Vec2& u) {
  const TexelSample t = static_cast<const D&>(*s.distribution_).pick(u);
  const RowBand& band = s.g_->rows[std::size_t(t.y)];
  // pdf: the same product as pdf(direction).
  return DirectionSample{s.latlong_direction<kOneStep>(band, t.x, t.fx, t.fy), t.pdf * band.pdf_factor, t.x, t.y};
}

DirectionSample SphericalDistribution::sample_general(const SphericalDistribution& s, const Vec2& u) {
  const TexelSample t = s.distribution_->sample_texel(u);
  if (s.grid_ == Kind::LatLong) {
    const RowBand& band = s.g_->rows[std::size_t(t.y)];
    return DirectionSample{s.latlong_direction<false>(band, t.x, t.fx, t.fy), t.pdf * band.pdf_factor, t.x, t.y};
  }
  return DirectionSample{s.direction_in_texel(t.x, t.y, t.fx, t.fy), t.pdf * s.g_->equal_area_pdf_factor, t.x, t.y};
}

template <bool kOneStep>
void SphericalDistribution::latlong_directions(const TexelSample* t, DirectionSample* out, std::size_t n) const {
  // Row bands (a cache line per row) and longitude entries are read at random on a big grid: prefetch the whole
  // group's first, then form the directions (the arithmetic of sample_latlong, so the same bits).
  for (std::size_t k = 0; k < n; ++k) {
    __builtin_prefetch(g_->rows.data() + t[k].y);
    __builtin_prefetch(g_->longitudes.data() + std::size_t(t[k].x) * std::size_t(g_->longitude_substeps));
  }
  for (std::size_t k = 0; k < n; ++k) {
    const RowBand& band = g_->rows[std::size_t(t[k].y)];
    out[k] = DirectionSample{latlong_direction<kOneStep>(band, t[k].x, t[k].fx, t[k].fy), t[k].pdf * band.pdf_factor,
                             t[k].x, t[k].y};
  }
}

void SphericalDistribution::sample(std::span<const Vec2> u, std::span<DirectionSample> out) const {
  if (u.size() != out.size())
    throw Error("spherical distribution: sample() of " + std::to_string(u.size()) + " u into " +
                std::to_string(out.size()) + " results");
  TexelSample t[sampling::kSampleGroup];
  sampling::for_each_group(u.size(), [&](std::size_t g, std::size_t n) {
    distribution_->sample_texels(u.subspan(g, n), std::span<TexelSample>(t, n));
    DirectionSample* o = out.data() + g;
    if (grid_ != Kind::LatLong) {
      // Equal-area grids: no table is read after the texel choice (as sample_general).
      for (std::size_t k = 0; k < n; ++k)
        o[k] = DirectionSample{direction_in_texel(t[k].x, t[k].y, t[k].fx, t[k].fy),
                               t[k].pdf * g_->equal_area_pdf_factor, t[k].x, t[k].y};
    } else if (g_->longitude_substeps == 1) {
      latlong_directions<true>(t, o, n);
    } else {
      latlong_directions<false>(t, o, n);
    }
  });
}

void SphericalDistribution::sample_each(std::span<const SphericalDistribution* const> from, std::span<const Vec2> u,
                                        std::span<DirectionSample> out) {
  if (from.size() != u.size() || u.size() != out.size())
    throw Error("spherical distribution: sample_each() of " + std::to_string(u.size()) + " u from " +
                std::to_string(from.size()) + " distributions into " + std::to_string(out.size()) + " results");
  const RefinedDistribution2D* refined[sampling::kDrawGroup];
  TexelSample t[sampling::kDrawGroup];
  sampling::for_each_group(
      u.size(),
      [&](std::size_t g, std::size_t n) {
        bool together = n > 1;
        for (std::size_t k = 0; k < n && together; ++k) {
          const SphericalDistribution& d = *from[g + k];
          together = d.grid_ == Kind::LatLong && d.builtin_ == BuiltinDistribution::Refined && d.g_ == from[g]->g_;
          if (together) refined[k] = &static_cast<const RefinedDistribution2D&>(*d.distribution_);
        }
        if (!together) {
          for (std::size_t k = 0; k < n; ++k) out[g + k] = from[g + k]->sample(u[g + k]);
          return;
        }
        RefinedDistribution2D::pick_group(refined, u.data() + g, t, n);
        // The directions as sample_latlong forms them (the same arithmetic, so the same bits).
        const SphericalDistribution& d = *from[g];
        for (std::size_t k = 0; k < n; ++k) {
          const RowBand& band = d.g_->rows[std::size_t(t[k].y)];
          const Vec3 direction = d.g_->longitude_substeps == 1
                                     ? d.latlong_direction<true>(band, t[k].x, t[k].fx, t[k].fy)
                                     : d.latlong_direction<false>(band, t[k].x, t[k].fx, t[k].fy);
          out[g + k] = DirectionSample{direction, t[k].pdf * band.pdf_factor, t[k].x, t[k].y};
        }
      },
      sampling::kDrawGroup);
}

double SphericalDistribution::pdf(const Vec3& direction) const {
  if (!finite_nonzero(direction)) return 0.0;
  int x = 0, y = 0;
  texel_of(direction, x, y);
  return texel_pdf(x, y);
}

double SphericalDistribution::texel_pdf(int x, int y) const {
  const double factor = grid_ == Kind::LatLong ? g_->rows[std::size_t(y)].pdf_factor : g_->equal_area_pdf_factor;
  // The pyramid tables' density of the texel itself: what pdf() of the texel's centre returns (its uv names the
  // texel again), without the virtual call and the round trip through uv.
  if (builtin_ == BuiltinDistribution::Refined)
    return static_cast<const RefinedDistribution2D&>(*distribution_).texel_pdf(x, y) * factor;
  if (builtin_ == BuiltinDistribution::Hierarchical && x >= 0 && y >= 0 && x < width() && y < height())
    return static_cast<const HierarchicalDistribution2D&>(*distribution_).texel_pdf(x, y) * factor;
  const Vec2 centre((x + 0.5) / width(), (y + 0.5) / height());
  return distribution_->pdf(centre) * factor;
}

Vec2 SphericalDistribution::invert(const Vec3& direction) const {
  int x = 0, y = 0;
  double fx = 0.0, fy = 0.0;
  locate(direction, x, y, fx, fy);
  // Keep the position inside texel (x, y): fx = 1 would name the next texel.
  fx = sampling::clamp_offset(fx);
  fy = sampling::clamp_offset(fy);
  return distribution_->invert(Vec2((x + fx) / width(), (y + fy) / height()));
}

}  // namespace envkit
