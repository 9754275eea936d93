#include <envkit/core/error.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/resample.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "cube_projection.h"
#include "resample_common.h"

namespace envkit {

using namespace detail;

namespace {

// Source position seen by an output direction; false when it falls outside the source image (cropped balls).
bool source_position(const Parameterization& src, const Mat3& dst_to_src, bool rotate, const Vec3& dir, Vec2& p) {
  p = src.to_image(rotate ? apply(dst_to_src, dir) : dir);
  return p.x >= 0.0 && p.y >= 0.0 && p.x <= src.width() && p.y <= src.height();
}

// Direction seen at the centre of output texel (i, j), or at some covered point of a rim texel.
bool output_direction(const TexelDirections& dirs, const Parameterization& dst, int i, int j, Vec3& dir) {
  if (dirs.centre(i, j, dir)) return true;
  Vec2 q;
  return dst.covered_point(i, j, q) && dst.to_direction(q, dir);
}

Image resample_point(const MapRef& s, const TexelSource& source, const Parameterization& dst, const Mat3& dst_to_src,
                     const ResampleOptions& opt) {
  const OutputLayout o = output_layout(s.image, source);
  Image out = make_output(s.image, dst, o);
  const int C = s.image.channels;
  const bool rotate = !is_identity(dst_to_src);
  const TexelDirections dirs(dst);
  ProgressCounter progress(opt.progress, static_cast<std::size_t>(dst.height()));
  tbb::parallel_for(0, dst.height(), [&](int j) {
    std::vector<float> value(C);
    for (int i = 0; i < dst.width(); ++i) {
      float* px = out.at(i, j);
      Vec3 dir;
      Vec2 p;
      if (!output_direction(dirs, dst, i, j, dir) || !source_position(s.param, dst_to_src, rotate, dir, p)) continue;
      // Every filter reconstructs a texel at its own centre as its value, bilinear and bicubic only up to the
      // round-off of the direction round trip: a coinciding texel is copied.
      if (const auto t = coincident_source_texel(s.param, dst, dst_to_src, rotate, i, j, p); t >= 0) {
        apply_texel_copies(s.image, {{static_cast<std::size_t>(j) * dst.width() + i, std::size_t(t)}}, o, out);
        continue;
      }
      const bool ok = source.sample(p, opt.filter, value.data());
      for (int c = 0; c < C; ++c) px[c] = value[c];
      if (o.add_coverage) px[o.alpha] = ok ? 1.0f : 0.0f;
    }
    progress.add(1);
  });
  return out;
}

// Angular size (radians, about the side) of output texel (i, j), from its corners: this also catches the long thin
// texels near a mirror ball's rim that an area ratio would miss. Lat-long rows are measured exactly instead.
// Negative when a corner has no data (a texel straddling a rim).
double texel_extent(const Parameterization& dst, const std::vector<double>& latlong_row_extent, const Vec3& centre,
                    int i, int j) {
  if (!latlong_row_extent.empty()) return latlong_row_extent[j];
  const double inset = 1e-6;  // corners just inside the texel, so they belong to its face/disk
  const Vec2 corners[4] = {Vec2(i + inset, j + inset), Vec2(i + 1 - inset, j + inset), Vec2(i + inset, j + 1 - inset),
                           Vec2(i + 1 - inset, j + 1 - inset)};
  double extent = 0.0;
  for (const Vec2& c : corners) {
    Vec3 d;
    if (!dst.to_direction(c, d)) return -1.0;
    extent = std::max(extent, (d - centre).length());  // chord: the angle to within 1% below 0.3 rad, no atan2
  }
  return 2.0 * extent / std::sqrt(2.0);  // corner-to-centre is half the footprint's diagonal
}

// Larger side of each lat-long row's texels in radians: the polar span or the widest parallel it crosses.
std::vector<double> latlong_row_extents(const Parameterization& dst) {
  const LatLongMap* ll = dst.latlong_geometry();
  if (!ll) return {};
  std::vector<double> extent(dst.height());
  for (int j = 0; j < dst.height(); ++j) {
    const Vec2 a = ll->domain_from_image(Vec2(0.0, j)), b = ll->domain_from_image(Vec2(1.0, j + 1.0));
    const double v0 = std::clamp(a.y, 0.0, 1.0), v1 = std::clamp(b.y, 0.0, 1.0);
    const double widest = (v0 <= 0.5 && v1 >= 0.5)
                              ? 1.0
                              : std::max(std::sin(LatLongMap::polar_angle(v0)), std::sin(LatLongMap::polar_angle(v1)));
    extent[j] = std::max(LatLongMap::kRadiansPerV * (v1 - v0), LatLongMap::kRadiansPerU * (b.x - a.x) * widest);
  }
  return extent;
}

// Solid angle of the source's smallest texel that holds data (0 if none does).
double smallest_positive_texel(const Parameterization& p, const SolidAngleTable& omega) {
  double smallest = 0.0;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i)
      if (const double w = omega(i, j); w > 0.0 && (smallest == 0.0 || w < smallest)) smallest = w;
  return smallest;
}

}  // namespace

Image detail::resample_area_gather(const MapRef& s, const TexelSource& full_source, const Parameterization& dst,
                                   const Mat3& dst_to_src, const ResampleOptions& opt, const AreaTables& omega,
                                   GatherKernel kernel) {
  const Image& img = s.image;
  const Parameterization& sp = s.param;
  const int C = img.channels;
  const OutputLayout o = output_layout(img, full_source);
  Image out = make_output(img, dst, o);
  const SolidAngleTable& src_omega = omega.src;
  const SolidAngleTable& dst_omega = omega.dst;
  const bool rotate = !is_identity(dst_to_src);
  const TexelDirections dirs(dst);
  const std::vector<double> row_extent = latlong_row_extents(dst), src_row_extent = latlong_row_extents(sp);
  std::vector<TexelCopies> copies(static_cast<std::size_t>(dst.height()));

  // 1. Split off the hot texels: they are splatted exactly below, the cold remainder is gathered.
  const std::vector<std::size_t> hot = find_hot_texels(img, src_omega, opt.hot_fraction, opt.hot_contrast);
  Image cold_copy;
  const Image* cold = &img;
  if (!hot.empty()) {
    cold_copy = img;
    for (std::size_t t : hot)
      for (int c = 0; c < C; ++c)
        if (c != img.alpha_channel) cold_copy.pixels[t * C + c] = 0.0f;
    cold = &cold_copy;
  }
  const TexelSource source(*cold, sp);

  // 2. Gather the cold part: supersample each output texel on an n x n grid, n adapted to how many source texels
  // its footprint spans; weights = the sub-cells' solid angles. The batched kernel projects a row's centres at once
  // (on lanes: lat-long rows into a cube) and asks whether a texel coincides with a source texel only where their
  // solid angles agree; the per-texel kernel is the reference.
  const bool batched = kernel == GatherKernel::Batched;
  const std::unique_ptr<LatLongRowsInCube> rows =
      batched ? LatLongRowsInCube::make(dst, sp, dst_to_src, rotate) : nullptr;
  // With rows, the source's smallest texel answers for a whole output row (the cube source's texels all hold data)
  // what the per-texel tests would: whether any texel of the row could coincide with a source texel (their solid
  // angles must agree), and whether every one is magnified (no more than one sub-sample per axis).
  const double min_source_omega = rows ? smallest_positive_texel(sp, src_omega) : 0.0;
  ProgressCounter progress(opt.progress, static_cast<std::size_t>(dst.height()));
  tbb::parallel_for(0, dst.height(), [&](int j) {
    std::vector<double> sum(C);
    const std::size_t row_size = rows ? static_cast<std::size_t>(dst.width()) : 0;
    const auto row_x = std::make_unique_for_overwrite<double[]>(row_size);
    const auto row_y = std::make_unique_for_overwrite<double[]>(row_size);
    Tap taps[16];
    const auto add_taps = [&](Vec2 p, double w) {
      const int k = source.taps(p, Filter::Bilinear, taps);
      for (int t = 0; t < k; ++t) {
        const float* px = cold->pixels.data() + taps[t].index * C;
        const double tw = w * taps[t].weight;
        for (int c = 0; c < C; ++c) sum[c] += tw * px[c];
      }
      return k > 0;
    };
    bool row_cannot_coincide = false, row_magnified = false;
    if (rows) {
      rows->project(j, 0, dst.width(), row_x.get(), row_y.get());
      const double largest = std::max(dst_omega(0, j), dst_omega(std::min(1, dst.width() - 1), j));  // lat-long rows
      row_cannot_coincide = largest < (1.0 - 1e-3) * min_source_omega;
      row_magnified = opt.supersampling * row_extent[j] <= std::sqrt(min_source_omega) * (1.0 + 1e-6);
    }
    for (int i = 0; i < dst.width(); ++i) {
      const double omega_t = dst_omega(i, j);
      if (omega_t <= 0.0) continue;
      double covered_weight = 0.0, total_weight = 0.0;
      Vec3 centre(0.0, 0.0, 0.0);  // set where rows does not project: texel_extent reads it for other outputs only
      Vec2 pc;
      bool centre_in_source;
      if (rows) {  // a lat-long output: every centre has a direction, and a cube source sees every direction
        pc = Vec2(row_x[i], row_y[i]);
        centre_in_source = true;
      } else {
        centre_in_source = dirs.centre(i, j, centre) && source_position(sp, dst_to_src, rotate, centre, pc);
      }
      // A texel can coincide with a source texel only if their solid angles agree (to well within this, whatever
      // the tables' float precision): others need not be asked.
      const auto may_coincide = [&] {
        const int si = std::clamp(static_cast<int>(pc.x), 0, sp.width() - 1);
        const int sj = std::clamp(static_cast<int>(pc.y), 0, sp.height() - 1);
        return std::abs(omega_t - src_omega(si, sj)) <= 1e-3 * src_omega(si, sj);
      };
      if (centre_in_source && !row_cannot_coincide && (!batched || may_coincide())) {
        const auto t = coincident_source_texel(sp, dst, dst_to_src, rotate, i, j, pc);
        if (t >= 0) {
          // Written after the hot texels' splat, which also reaches this texel from its own source texel only.
          copies[j].emplace_back(static_cast<std::size_t>(j) * dst.width() + i, std::size_t(t));
          continue;
        }
      }
      // Sub-samples per axis: `supersampling` per source texel across the footprint, at most max_subsamples.
      int n = opt.max_subsamples;
      if (row_magnified) {
        n = 1;  // what the test below gives each texel of the row, its source texel being no smaller
      } else if (centre_in_source) {
        const double extent = texel_extent(dst, row_extent, centre, i, j);
        const int si = std::clamp(static_cast<int>(pc.x), 0, sp.width() - 1);
        const int sj = std::clamp(static_cast<int>(pc.y), 0, sp.height() - 1);
        double source_size = std::sqrt(std::max(src_omega(si, sj), 0.0));
        const double samples = opt.supersampling * extent;  // per axis, in units of the source texel size
        // An output texel no larger than the source texel it lands on (in solid angle) spans more than one source
        // texel only if it is also longer: then measure the source texel as the output texel is measured. Long thin
        // source texels (lat-long rows near the poles) are longer than the square root of their solid angle, so
        // same-size maps would otherwise be supersampled. A larger output texel keeps the square root: it may span
        // several of the thin texels across their narrow side.
        Vec3 source_centre;
        if (samples > source_size && dst_omega(i, j) <= src_omega(si, sj) * (1.0 + 1e-6) &&
            sp.to_direction(Vec2(si + 0.5, sj + 0.5), source_centre))
          source_size = std::max(source_size, texel_extent(sp, src_row_extent, source_centre, si, sj));
        if (extent >= 0.0 && source_size > 0.0)
          n = samples <= source_size * (1.0 + 1e-6)  // magnifying: the common case, without a division
                  ? 1
                  : std::clamp(static_cast<int>(std::ceil(samples / source_size - 1e-6)), 1, opt.max_subsamples);
      }
      if (n == 1 && centre_in_source) {
        // Magnifying (the common case here): the bilinear reconstruction at the centre, written directly.
        const int k = source.interior_bilinear_taps(pc, taps) ? 4 : source.taps(pc, Filter::Bilinear, taps);
        if (k > 0) {
          float* px = out.at(i, j);
          for (int c = 0; c < C; ++c) {
            double v = 0.0;
            for (int t = 0; t < k; ++t) v += double(taps[t].weight) * cold->pixels[taps[t].index * C + c];
            px[c] = static_cast<float>(v);
          }
          if (o.add_coverage) px[o.alpha] = 1.0f;
          continue;
        }
      }
      std::fill(sum.begin(), sum.end(), 0.0);
      if (n == 1) {
        total_weight = omega_t;
      } else {
        for (int b = 0; b < n; ++b) {
          for (int a = 0; a < n; ++a) {
            const Vec2 q(i + (a + 0.5) / n, j + (b + 0.5) / n);
            // Weights need only be proportional to each sub-cell's solid angle: the result is normalised below.
            const double w = dst.solid_angle_density(q);
            if (w <= 0.0) continue;
            total_weight += w;
            Vec3 dir;
            Vec2 p;
            if (dst.to_direction(q, dir) && source_position(sp, dst_to_src, rotate, dir, p) && add_taps(p, w))
              covered_weight += w;
          }
        }
      }
      // A sliver of data (a rim texel whose sub-samples all fell outside the disk): sample its covered point.
      Vec2 q, p;
      Vec3 dir;
      if (covered_weight == 0.0 && dst.covered_point(i, j, q) && dst.to_direction(q, dir) &&
          source_position(sp, dst_to_src, rotate, dir, p) && add_taps(p, 1.0))
        covered_weight = total_weight = 1.0;
      float* px = out.at(i, j);
      if (covered_weight > 0.0)
        for (int c = 0; c < C; ++c) px[c] = static_cast<float>(sum[c] / covered_weight);
      if (o.add_coverage)
        px[o.alpha] = static_cast<float>(covered_weight / std::max(total_weight, 1e-300));
      else if (o.alpha >= 0 && covered_weight > 0.0)
        px[o.alpha] = static_cast<float>(sum[o.alpha] / total_weight);  // source alpha, fading where uncovered
    }
    progress.add(1);
  });

  // 3. Splat the hot texels: flux L x (exact sub-cell solid angle) into the output texel that sees each sub-cell.
  splat_hot_texels(s, hot, src_omega, dst, dst_omega, dst_to_src, out);
  merge_twin_texels(dst, dst_omega, out);  // a hot texel on a seam reaches one copy only
  for (const TexelCopies& row : copies) apply_texel_copies(img, row, o, out);
  return out;
}

namespace {

/// Mean solid angle of the texels that hold data.
double mean_texel_solid_angle(const Parameterization& p, const SolidAngleTable& omega) {
  return omega.total() / std::max(1.0, double(p.width()) * double(p.height()));
}

}  // namespace

std::vector<double> total_power(const Image& image, const Parameterization& param) {
  const SolidAngleTable omega(param);
  const int C = image.channels;
  std::vector<std::vector<double>> rows(image.height, std::vector<double>(C, 0.0));
  tbb::parallel_for(0, image.height, [&](int j) {
    for (int i = 0; i < image.width; ++i) {
      const double w = omega(i, j);
      if (w <= 0.0) continue;
      const float* px = image.at(i, j);
      for (int c = 0; c < C; ++c)
        if (std::isfinite(px[c])) rows[j][c] += w * px[c];
    }
  });
  std::vector<double> power(C, 0.0);
  for (const auto& r : rows)
    for (int c = 0; c < C; ++c) power[c] += r[c];
  return power;
}

AreaMethod detail::choose_area_method(const Parameterization& src, const Parameterization& dst,
                                      const TexelSource& source, const AreaTables& omega) {
  // The scatter needs a direction for every source texel: sources with blank texels (balls, crosses) gather.
  if (!source.fully_covered()) return AreaMethod::Gather;
  // Disk maps' rim texels are long and thin, far from the squares the scatter spreads over.
  if (dst.kind() == Kind::MirrorBall || dst.kind() == Kind::AngularMap) return AreaMethod::Gather;
  if (omega.src.total() < 0.999 * kFourPi) return AreaMethod::Gather;
  const double ratio = mean_texel_solid_angle(dst, omega.dst) / mean_texel_solid_angle(src, omega.src);
  return ratio >= kScatterMinRatio ? AreaMethod::Scatter : AreaMethod::Gather;
}

AreaMethod choose_area_method(const Parameterization& src, const Parameterization& dst, const TexelSource& source) {
  return detail::choose_area_method(src, dst, source, detail::AreaTables(src, dst));
}

Image resample(const MapRef& src, const Parameterization& dst, const Mat3& dst_to_world, const ResampleOptions& opt) {
  if (src.image.empty()) throw Error("cannot resample an empty image");
  const TexelSource source(src.image, src.param);
  const Mat3 dst_to_src = compose(transposed(src.to_world), dst_to_world);
  // Every filter reproduces a map on its own grid (the mean over a texel is the texel): copy, exactly.
  if (is_identity(dst_to_src, 1e-12) && src.param.same_grid(dst))
    return copy_same_grid(src.image, dst, output_layout(src.image, source));
  if (opt.filter != Filter::Area) return resample_point(src, source, dst, dst_to_src, opt);
  const detail::AreaTables omega(src.param, dst);
  AreaMethod method = opt.area_method;
  if (method == AreaMethod::Auto) method = detail::choose_area_method(src.param, dst, source, omega);
  if (method == AreaMethod::Scatter) {
    if (!source.fully_covered()) throw Error("area scatter needs a source with data in every texel");
    return resample_area_scatter(src, source, dst, dst_to_src, opt, omega);
  }
  return resample_area_gather(src, source, dst, dst_to_src, opt, omega, GatherKernel::Batched);
}

}  // namespace envkit
