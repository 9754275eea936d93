#include <envkit/core/error.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/filter.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <mutex>
#include <optional>

#include "moment_tree.h"

namespace envkit {

std::string roughness_mapping_name(RoughnessMapping mapping) {
  switch (mapping) {
    case RoughnessMapping::Gltf:
      return "gltf";
    case RoughnessMapping::Filament:
      return "filament";
    case RoughnessMapping::Unreal:
      return "unreal";
  }
  return "gltf";
}

RoughnessMapping parse_roughness_mapping(const std::string& name) {
  if (name == "gltf" || name == "khronos") return RoughnessMapping::Gltf;
  if (name == "filament") return RoughnessMapping::Filament;
  if (name == "unreal" || name == "ue4" || name == "ue") return RoughnessMapping::Unreal;
  throw Error("unknown roughness mapping '" + name + "' (expected gltf, filament or unreal)");
}

double level_roughness(RoughnessMapping mapping, int level, int levels) {
  if (levels <= 1) return 0.0;
  const double lod = std::clamp(double(level) / (levels - 1), 0.0, 1.0);
  switch (mapping) {
    case RoughnessMapping::Gltf:
      return lod;
    case RoughnessMapping::Filament:
      return 1.0 - std::sqrt(1.0 - lod);
    case RoughnessMapping::Unreal: {
      const double level_from_1x1 = (levels - 1) - level;
      return std::min(1.0, std::exp2((1.0 - level_from_1x1) / 1.2));
    }
  }
  return lod;
}

double ggx_d(double n_dot_h, double alpha) {
  const double a2 = alpha * alpha;
  const double t = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
  return t > 0.0 ? a2 / (kPi * t * t) : 0.0;
}

std::unique_ptr<Parameterization> prefilter_level_param(Kind kind, int size, CubeBasis basis, TexelGrid grid) {
  if (kind == Kind::CubeMap) return std::make_unique<CubeMap>(size, CubeLayout::VerticalStrip, basis, grid);
  if (kind == Kind::Octahedral) return std::make_unique<OctahedralMap>(size);
  throw Error("prefilter: output must be a cube or an octahedral map, not " + kind_name(kind));
}

namespace {

// The split-sum weight D(n.h) (n.l) as a function of c = r.l (n = v = r, so
// (n.h)^2 = (1 + c) / 2), without the constant 1/pi, which the normalisation
// cancels.
inline double lobe_weight(double c, double a2) {
  if (c <= 0.0) return 0.0;
  const double t = 0.5 * (1.0 + c) * (a2 - 1.0) + 1.0;
  return c * a2 / (t * t);
}

// One output level: the split-sum average at every texel centre of `param` (map
// frame -> world by to_world).
Image convolve_level(const detail::MomentTree& tree, const Parameterization& param, const Mat3& to_world,
                     const Image& like, double alpha, double accuracy, const std::function<void(int)>& rows_done) {
  const TexelDirections dirs(param);
  Image out(param.width(), param.height(), like.channels);
  out.channel_names = like.channel_names;
  out.alpha_channel = like.alpha_channel;
  // Blocks of 4 x 4 texels walk the tree together (MomentTree::filter): neighbours on the map, and on the sphere
  // but where a block crosses a cube face's edge, which costs only time.
  constexpr int kBlock = 4;
  static_assert(kBlock * kBlock <= detail::MomentTree::kMaxGroup);
  const detail::MomentTree::Walk walk = tree.walk(alpha, accuracy);
  const int rows = (out.height + kBlock - 1) / kBlock;
  tbb::parallel_for(0, rows, [&](int by) {
    const int y0 = by * kBlock, y1 = std::min(out.height, y0 + kBlock);
    std::array<Vec3, kBlock * kBlock> r;
    std::array<float*, kBlock * kBlock> px;
    std::array<float, kBlock * kBlock * 4> values;
    for (int x0 = 0; x0 < out.width; x0 += kBlock) {
      int n = 0;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < std::min(out.width, x0 + kBlock); ++x) {
          Vec3 d;
          float* p = out.at(x, y);
          if (!dirs.centre(x, y, d)) {
            std::fill(p, p + out.channels, 0.0f);
            continue;
          }
          r[n] = apply(to_world, d).normalized();
          px[n++] = p;
        }
      if (n == 0) continue;
      tree.filter(walk, std::span(r.data(), n), std::span(values.data(), std::size_t(n) * out.channels));
      for (int t = 0; t < n; ++t) std::copy_n(values.data() + std::size_t(t) * out.channels, out.channels, px[t]);
    }
    if (rows_done) rows_done(out.width * (y1 - y0));
  });
  return out;
}

// The alpha level m is filtered with (the mapping's r^2, kept off 0 where the lobe would have no width).
double level_alpha(RoughnessMapping mapping, int m, int levels) {
  const double r = level_roughness(mapping, m, levels);
  return std::max(r * r, 1e-4);
}

int power_of_two_at_least(int n) {
  int p = 1;
  while (p < n) p *= 2;
  return p;
}

int full_chain_levels(int size) {
  int levels = 1;
  while ((size >> levels) >= 1) ++levels;
  return levels;
}

// The walk refines a node while its radius exceeds accuracy x 2 alpha, or, across the horizon, 0.25 accuracy /
// alpha (prefilter.h): the smallest radius any level of the chain refines.
double finest_refined_radius(const PrefilterOptions& options, int levels) {
  double radius = kPi;
  for (int m = 1; m < levels; ++m) {
    const double alpha = level_alpha(options.mapping, m, levels);
    radius = std::min(radius, options.accuracy * std::min(2.0 * alpha, 0.25 / alpha));
  }
  return radius;
}

// The moment tree stays within this many times the source image's own bytes. A cube coarser than the
// lobes need costs walk time only, never accuracy: the walk refines its finest nodes into their source texels.
constexpr double kSourceCubeBytesPerSourceByte = 4.0;

// The largest face size whose tree keeps to that budget. It also holds fewer finest nodes than the source has
// texels (a node costs more bytes than a texel's budget), so the cube is never finer than the source.
int source_cube_size_cap(const MapRef& src) {
  const double source_bytes = double(src.image.texel_count()) * src.image.channels * sizeof(float);
  int n = 1;
  while (2 * n <= detail::MomentTree::kMaxFaceSize &&
         detail::MomentTree::peak_bytes(2 * n) <= kSourceCubeBytesPerSourceByte * source_bytes)
    n *= 2;
  return n;
}

// The first face size whose texels are within the finest radius any level refines (all the walk can use), unless
// the memory cap stops it first: then the walk refines the finest nodes into their texels. The output's size plays
// no part: a level's lobe may be much narrower than one of its texels.
int default_source_size(const MapRef& src, double finest_radius) {
  const int cap = source_cube_size_cap(src);
  int size = 1;
  while (size < cap && detail::MomentTree::texel_radius(size) > finest_radius) size *= 2;
  return size;
}

}  // namespace

PrefilteredChain prefilter_ggx(const MapRef& src, const PrefilterOptions& options) {
  if (options.size < 1) throw Error("prefilter: size must be at least 1");
  if (!(options.accuracy > 0.0)) throw Error("prefilter: accuracy must be positive");
  if (src.image.channels > 4) throw Error("prefilter: at most 4 channels");
  const int max_levels = full_chain_levels(options.size);
  const int levels = options.levels == 0 ? max_levels : options.levels;
  if (levels < 1 || levels > max_levels)
    throw Error("prefilter: " + std::to_string(levels) + " levels requested; a size of " +
                std::to_string(options.size) + " has at most " + std::to_string(max_levels));
  const double finest_radius = finest_refined_radius(options, levels);
  int source_size = options.source_size == 0 ? default_source_size(src, finest_radius) : options.source_size;
  if (source_size < 1 || (source_size & (source_size - 1)) != 0)
    throw Error("prefilter: source size must be a power of two, not " + std::to_string(source_size));

  // Progress: the resampling passes take the first 30%, the levels the rest in
  // proportion to their texels.
  std::mutex progress_mutex;
  auto report = [&](double f) {
    if (!options.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    options.progress(std::clamp(f, 0.0, 1.0));
  };

  PrefilteredChain chain;
  chain.mapping = options.mapping;
  chain.source_size = source_size;
  chain.cube_basis = options.cube_basis;
  chain.cube_grid = options.cube_grid;

  auto level0_param = prefilter_level_param(options.kind, options.size, options.cube_basis, options.cube_grid);
  const bool openexr_faces = options.kind == Kind::CubeMap && options.cube_basis == CubeBasis::Envkit &&
                             options.cube_grid == TexelGrid::Corner;
  ResampleOptions area;
  area.filter = Filter::Area;
  area.progress = [&](double f) { report(0.25 * f); };
  Image level0 = resample(src, *level0_param, options.to_world, area);

  std::optional<detail::MomentTree> tree;
  if (levels > 1) tree.emplace(src, source_size, detail::MomentTree::texel_radius(source_size) > finest_radius);
  report(0.3);

  auto make_level = [&](Image image, std::unique_ptr<Parameterization> param, int m) {
    EnvMap map;
    map.image = std::move(image);
    map.param = std::move(param);
    map.convention = openexr_faces ? "openexr" : "gl";
    map.rotation = options.to_world;
    const double r = level_roughness(options.mapping, m, levels);
    map.image.metadata["envkit:ibl_roughness_mapping"] = roughness_mapping_name(options.mapping);
    map.image.metadata["envkit:ibl_level"] = std::to_string(m);
    map.image.metadata["envkit:ibl_roughness"] = std::to_string(r);
    map.image.metadata["envkit:ibl_alpha"] = std::to_string(m == 0 ? 0.0 : r * r);
    chain.roughness.push_back(r);
    chain.alpha.push_back(m == 0 ? 0.0 : r * r);
    chain.levels.push_back(std::move(map));
  };
  make_level(std::move(level0), std::move(level0_param), 0);

  double total_texels = 0.0;
  for (int m = 1; m < levels; ++m) total_texels += double(std::max(1, options.size >> m)) * (options.size >> m);
  std::atomic<long long> done{0};
  for (int m = 1; m < levels; ++m) {
    const int n = std::max(1, options.size >> m);
    auto param = prefilter_level_param(options.kind, n, options.cube_basis, options.cube_grid);
    const double alpha = level_alpha(options.mapping, m, levels);
    const double per_texel = 1.0 / std::max(1.0, total_texels * (options.kind == Kind::CubeMap ? 6.0 : 1.0));
    Image out = convolve_level(*tree, *param, options.to_world, chain.levels[0].image, alpha, options.accuracy,
                               [&](int texels) {
                                 const long long now = done.fetch_add(texels) + texels;
                                 report(0.3 + 0.7 * double(now) * per_texel);
                               });
    out.metadata = src.image.metadata;
    make_level(std::move(out), std::move(param), m);
  }
  report(1.0);
  return chain;
}

EnvMap irradiance_map(const MapRef& src, const IrradianceOptions& options) {
  if (options.size < 1) throw Error("irradiance: size must be at least 1");
  if (!(options.accuracy > 0.0)) throw Error("irradiance: accuracy must be positive");
  if (src.image.channels > 4) throw Error("irradiance: at most 4 channels");
  const int source_size =
      options.source_size == 0 ? power_of_two_at_least(std::max(options.size, 32)) : options.source_size;
  if ((source_size & (source_size - 1)) != 0)
    throw Error("irradiance: source size must be a power of two, not " + std::to_string(source_size));
  const detail::MomentTree tree(src, source_size);
  EnvMap map;
  map.param = prefilter_level_param(options.kind, options.size);
  map.convention = "gl";
  map.rotation = options.to_world;
  Image like(1, 1, src.image.channels);
  like.channel_names = src.image.channel_names;
  like.alpha_channel = src.image.alpha_channel;
  // With alpha = 1 the GGX weight D (n.l) is the clamped cosine / pi: the level
  // is E / pi.
  map.image = convolve_level(tree, *map.param, options.to_world, like, 1.0, options.accuracy, {});
  if (!options.divide_by_pi)
    for (int y = 0; y < map.image.height; ++y)
      for (int x = 0; x < map.image.width; ++x)
        for (int c = 0; c < map.image.channels; ++c)
          if (c != map.image.alpha_channel) map.image.at(x, y, c) *= float(kPi);
  map.image.metadata = src.image.metadata;
  map.image.metadata["envkit:ibl_irradiance"] = options.divide_by_pi ? "E/pi" : "E";
  return map;
}

GgxReference::GgxReference(const MapRef& src) : image_(src.image) {
  const TexelDirections dirs(src.param);
  const SolidAngleTable omega(src.param);
  const TexelSource source(src.image, src.param);
  dirs_.resize(src.image.texel_count());
  omega_.resize(src.image.texel_count());
  for (int y = 0; y < src.image.height; ++y)
    for (int x = 0; x < src.image.width; ++x) {
      const std::size_t i = std::size_t(y) * src.image.width + x;
      Vec3 d;
      if (!source.covered(i) || !dirs.centre(x, y, d)) continue;
      dirs_[i] = apply(src.to_world, d).normalized();
      omega_[i] = omega(x, y);
    }
}

void GgxReference::eval(const Vec3& r, double alpha, double* out) const {
  const int channels = image_.channels;
  std::vector<double> acc(channels, 0.0);
  double weight = 0.0;
  const double a2 = alpha * alpha;
  std::size_t nearest = 0;
  double best = -2.0;
  for (std::size_t i = 0; i < dirs_.size(); ++i) {
    if (omega_[i] <= 0.0) continue;
    const double c = r ^ dirs_[i];
    if (c > best) {
      best = c;
      nearest = i;
    }
    const double w = lobe_weight(c, a2) * omega_[i];
    if (w <= 0.0) continue;
    const float* px = image_.pixels.data() + i * channels;
    for (int ch = 0; ch < channels; ++ch) acc[ch] += w * px[ch];
    weight += w;
  }
  for (int ch = 0; ch < channels; ++ch) {
    const double v = alpha > 0.0 ? (weight > 0.0 ? acc[ch] / weight : 0.0) : image_.pixels[nearest * channels + ch];
    out[ch] = std::isfinite(v) ? v : 0.0;
  }
}

}  // namespace envkit
