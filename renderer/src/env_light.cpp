#include <envkit/core/error.h>
#include <envkit/maps/param_factory.h>
#include <envkit/render/env_light.h>
#include <envkit/resample/resample.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>

namespace envkit::render {

namespace {

/// True if `map` already is the distribution grid (same kind and size, centre-sampled, identity transform).
bool on_grid(const EnvMap& map, Kind grid, int width, int height) {
  if (map.param->kind() != grid || map.image.width != width || map.image.height != height) return false;
  return is_identity(map.to_world(), 1e-12) && map.param->grid() == TexelGrid::Centre;
}

bool same_frame(const Mat3& a, const Mat3& b) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (!(std::abs(a[r][c] - b[r][c]) <= 1e-9)) return false;
  return true;
}

double sanitize(float v) { return (std::isfinite(v) && v > 0.0f) ? double(v) : 0.0; }
float finite_float(double v) { return float(std::min(v, double(FLT_MAX))); }  // a bright texel x intensity stays finite

}  // namespace

EnvironmentLight::EnvironmentLight(const EnvMap& map, std::shared_ptr<const EnvTables> tables, const Mat3& rotation,
                                   double intensity)
    : tables_(std::move(tables)), rotation_(rotation), inverse_rotation_(transposed(rotation)), intensity_(intensity) {
  if (!tables_) throw Error("environment: no tables");
  if (!(intensity >= 0.0) || !std::isfinite(intensity)) throw Error("environment: intensity must be finite and >= 0");
  for (SamplingMethod m : {SamplingMethod::Hierarchical, SamplingMethod::Cdf, SamplingMethod::Alias})
    for (bool c : {false, true})
      if (!lookup_) lookup_ = tables_->distribution(m, c);
  if (!lookup_) throw Error("environment: the tables hold no distribution");
  // Radiance lives on the bake grid (grid_width x grid_height); the distribution may be coarser (--resolution).
  width_ = tables_->grid_width() > 0 ? tables_->grid_width() : tables_->width();
  height_ = tables_->grid_height() > 0 ? tables_->grid_height() : tables_->height();
  ParamSpec grid_spec;
  grid_spec.kind = tables_->grid();
  grid_spec.width = width_;
  grid_spec.height = height_;
  if (width_ != tables_->width() || height_ != tables_->height()) radiance_grid_ = make_parameterization(grid_spec);

  const Image* source = &map.image;
  Image resampled;
  if (!on_grid(map, tables_->grid(), width_, height_)) {
    const auto dst = make_parameterization(grid_spec);
    resampled = resample(map.ref(), *dst, identity3());
    source = &resampled;
  }
  const int colours = source->color_channels();
  texels_.resize(std::size_t(width_) * height_);
  tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < width_; ++x) {
        const float* p = source->at(x, y);
        Vec3 rgb = colours >= 3 ? Vec3(sanitize(p[0]), sanitize(p[1]), sanitize(p[2]))
                                : Vec3(sanitize(p[0]), sanitize(p[0]), sanitize(p[0]));
        rgb = rgb * intensity_;
        texels_[std::size_t(y) * width_ + x] = Texel{finite_float(rgb.x), finite_float(rgb.y), finite_float(rgb.z)};
      }
  });
}

std::size_t EnvironmentLight::texel_index(int x, int y) const {
  return std::size_t(std::clamp(y, 0, height_ - 1)) * std::size_t(width_) + std::size_t(std::clamp(x, 0, width_ - 1));
}

std::size_t EnvironmentLight::texel_index(const Vec3& table_dir) const {
  int x = 0, y = 0;
  if (radiance_grid_) {
    const Vec2 p = radiance_grid_->to_image(table_dir);
    x = std::isfinite(p.x) ? int(std::floor(p.x)) : 0;
    y = std::isfinite(p.y) ? int(std::floor(p.y)) : 0;
  } else {
    lookup_->texel_of(table_dir, x, y);
  }
  return texel_index(x, y);
}

Vec3 EnvironmentLight::radiance(const Vec3& d) const { return texels_[texel_index(apply(inverse_rotation_, d))].rgb(); }

const SphericalDistribution& EnvironmentLight::distribution(SamplingMethod method, bool compensated) const {
  const SphericalDistribution* d = tables_->distribution(method, compensated);
  if (!d) {
    std::string where = tables_->source_path().empty() ? "the tables" : "the tables of " + tables_->source_path();
    throw Error(where + " hold no " + table_name(method, compensated) + " table (bake it, or pass --bake)");
  }
  return *d;
}

namespace {

bool same_grid(const SphericalDistribution& a, const SphericalDistribution& b) {
  return a.grid() == b.grid() && a.width() == b.width() && a.height() == b.height();
}

/// u.x split at `share` in (0, 1]: below it, u.x / share for the second distribution; above, the rest re-uniformised
/// for the first. (Values outside [0, 1], NaN included, are clamped; the distributions clamp to [0, 1) themselves.)
Vec2 split_for_second(Vec2 u, double share, bool& second) {
  const double ux = u.x > 0.0 ? std::min(u.x, 1.0) : 0.0;
  second = ux < share || share >= 1.0;
  const double t = second ? ux / share : (ux - share) / (1.0 - share);
  return Vec2(std::min(t, 1.0), u.y);
}

}  // namespace

double EnvironmentLight::second_share(const LightTable& table) {
  if (!table.second) return 0.0;
  if (!same_grid(*table.first, *table.second))
    throw Error("environment: a mixture of light tables over different grids");
  return table.second_share > 0.0 ? std::min(table.second_share, 1.0) : 0.0;  // NaN: 0
}

LightSample EnvironmentLight::sample(const LightTable& table, Vec2 u) const {
  const double share = second_share(table);
  bool from_second = false;
  if (share > 0.0) u = split_for_second(u, share, from_second);
  return drawn(table, share, (from_second ? table.second : table.first)->sample(u));
}

LightSample EnvironmentLight::drawn(const LightTable& table, double share, const DirectionSample& ds) const {
  LightSample s;
  s.direction = apply(rotation_, ds.direction);
  s.pdf = share > 0.0 ? (1.0 - share) * table.first->texel_pdf(ds.x, ds.y) + share * table.second->texel_pdf(ds.x, ds.y)
                      : ds.pdf;
  // With a coarser distribution (radiance_grid_) its texel holds several radiance texels: search by direction.
  return prefetched(s, radiance_grid_ ? texel_index(ds.direction) : texel_index(ds.x, ds.y));
}

void EnvironmentLight::sample(const LightTable& table, std::span<const Vec2> u, std::span<LightSample> out) const {
  if (u.size() != out.size())
    throw Error("environment: " + std::to_string(u.size()) + " light samples into " + std::to_string(out.size()));
  // sample(table, u[k]) in three passes: the mixture's choices, the draws together, then each sample's density and
  // radiance texel as sample() forms them.
  constexpr std::size_t G = sampling::kDrawGroup;
  const double share = second_share(table);
  const SphericalDistribution* from[G];
  Vec2 v[G];
  DirectionSample ds[G];
  sampling::for_each_group(
      u.size(),
      [&](std::size_t g, std::size_t n) {
        for (std::size_t k = 0; k < n; ++k) {
          bool from_second = false;
          v[k] = share > 0.0 ? split_for_second(u[g + k], share, from_second) : u[g + k];
          from[k] = from_second ? table.second : table.first;
        }
        SphericalDistribution::sample_each(std::span<const SphericalDistribution* const>(from, n),
                                           std::span<const Vec2>(v, n), std::span<DirectionSample>(ds, n));
        for (std::size_t k = 0; k < n; ++k) out[g + k] = drawn(table, share, ds[k]);
      },
      G);
}

double EnvironmentLight::pdf(const LightTable& table, const Vec3& d) const {
  const Vec3 table_dir = apply(inverse_rotation_, d);
  const double share = second_share(table);
  const double first = share < 1.0 ? table.first->pdf(table_dir) : 0.0;
  return share > 0.0 ? (1.0 - share) * first + share * table.second->pdf(table_dir) : first;
}

LightSample EnvironmentLight::lookup(const LightTable& table, const Vec3& d) const {
  const SphericalDistribution& distribution = *table.first;
  if (radiance_grid_ || distribution.width() != width_ || distribution.height() != height_ ||
      distribution.grid() != lookup_->grid()) {
    LightSample s = lookup(d);
    s.pdf = pdf(table, d);
    return s;
  }
  const double share = second_share(table);
  int x = 0, y = 0;
  distribution.texel_of(apply(inverse_rotation_, d), x, y);
  LightSample s;
  s.direction = d;
  s.pdf = share > 0.0 ? (1.0 - share) * distribution.texel_pdf(x, y) + share * table.second->texel_pdf(x, y)
                      : distribution.texel_pdf(x, y);
  return prefetched(s, texel_index(x, y));
}

LightSample EnvironmentLight::lookup(const Vec3& d) const {
  LightSample s;
  s.direction = d;
  return prefetched(s, texel_index(apply(inverse_rotation_, d)));
}

LightSample EnvironmentLight::prefetched(LightSample s, std::size_t texel) const {
  // On maps larger than the caches this read is a miss; radiance(s) comes after the caller's shadow ray.
  s.texel = texel;
  __builtin_prefetch(texels_.data() + texel);
  return s;
}

Vec3 EnvironmentLight::mean_radiance() const {
  Vec3 sum(0, 0, 0);
  double omega = 0;
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      const double w = radiance_grid_ ? radiance_grid_->texel_solid_angle(x, y) : lookup_->texel_solid_angle(x, y);
      sum += texels_[std::size_t(y) * width_ + x].rgb() * w;
      omega += w;
    }
  return omega > 0 ? sum / omega : sum;
}

std::shared_ptr<const EnvTables> load_or_bake_tables(const EnvMap& map, const std::string& image_path,
                                                     const std::string& tables_path, bool bake, std::string* note) {
  // Tables record the hash of the source FILE bytes (what envbake checks and writes), six faces for a cube pattern.
  auto source_hash = [&]() -> std::string {
    if (image_path.empty()) return "";
    return file_content_hash(is_face_pattern(image_path) ? face_paths(image_path)
                                                         : std::vector<std::string>{image_path});
  };
  if (bake) {
    BakeOptions options;
    options.compensated = true;
    const auto start = std::chrono::steady_clock::now();
    auto tables = std::make_shared<EnvTables>(EnvTables::bake(map, options, image_path, source_hash()));
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (note) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "baked sampling tables in memory (%dx%d, %.0f ms)", tables->width(),
                    tables->height(), ms);
      *note = (image_path.empty() ? std::string() : image_path + ": ") + buf;
    }
    return tables;
  }
  if (tables_path.empty())
    fail(image_path, "no sampling table file given (set environment.tables, or pass --bake to bake in memory)");
  std::shared_ptr<const EnvTables> tables;
  try {
    tables = std::make_shared<EnvTables>(EnvTables::load(tables_path, source_hash()));
  } catch (const Error& e) {
    throw Error(std::string(e.what()) + " (pass --bake to bake the tables in memory)");
  }
  // The same file read with another convention puts the same texels in other directions: tables of the old frame
  // would sample the light where it is not (a biased image, fireflies), though the content hash matches.
  if (const auto& frame = tables->source_to_world(); frame && !same_frame(*frame, map.to_world()))
    fail(tables_path,
         "baked with another convention or orientation of the map than the scene's environment uses "
         "(re-bake with envbake --from-convention as in the scene, or pass --bake)");
  return tables;
}

}  // namespace envkit::render
