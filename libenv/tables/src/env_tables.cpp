// Baking importance tables from an environment map (see env_tables.h). The file format lives in
// env_tables_file.cpp.
#include <envkit/core/input_checks.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/color.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/resample/resample.h>
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/tables/env_tables.h>
#include <envkit/tables/sun_split.h>
#include <tbb/parallel_for.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#define XXH_INLINE_ALL
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

namespace envkit {

const char* importance_name(ImportanceMode mode) {
  switch (mode) {
    case ImportanceMode::Luminance:
      return "luminance";
    case ImportanceMode::Average:
      return "average";
    case ImportanceMode::Max:
      return "max";
  }
  return "?";
}

ImportanceMode parse_importance(const std::string& name) {
  if (name == "luminance") return ImportanceMode::Luminance;
  if (name == "average") return ImportanceMode::Average;
  if (name == "max") return ImportanceMode::Max;
  throw Error("unknown importance '" + name + "' (expected luminance, average or max)");
}

namespace {
/// The digest of a hash state as 32 hex digits; frees the state.
std::string finish_hash(XXH3_state_t* state) {
  const XXH128_hash_t h = XXH3_128bits_digest(state);
  XXH3_freeState(state);
  char text[33];
  std::snprintf(text, sizeof(text), "%016llx%016llx", static_cast<unsigned long long>(h.high64),
                static_cast<unsigned long long>(h.low64));
  return text;
}
}  // namespace

std::string image_content_hash(const Image& image) {
  XXH3_state_t* state = XXH3_createState();
  XXH3_128bits_reset(state);
  const std::int32_t dims[3] = {image.width, image.height, image.channels};
  XXH3_128bits_update(state, dims, sizeof(dims));
  for (const std::string& name : image.channel_names) XXH3_128bits_update(state, name.c_str(), name.size() + 1);
  XXH3_128bits_update(state, image.pixels.data(), image.pixels.size() * sizeof(float));
  return finish_hash(state);
}

std::string table_name(SamplingMethod method, bool compensated) {
  return std::string(method_name(method)) + (compensated ? "-compensated" : "");
}

std::string file_content_hash(const std::vector<std::string>& paths) {
  XXH3_state_t* state = XXH3_createState();
  XXH3_128bits_reset(state);
  std::vector<char> buffer(std::size_t(1) << 22);
  for (const std::string& path : paths) {
    if (std::filesystem::exists(path))
      require_regular_file(path);  // fopen() would block on a FIFO, /dev/zero would never end
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) {
      XXH3_freeState(state);
      throw Error(path + ": cannot open: " + std::strerror(errno));
    }
    std::size_t n;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), f)) > 0) XXH3_128bits_update(state, buffer.data(), n);
    const bool failed = std::ferror(f) != 0;
    std::fclose(f);
    if (failed) {
      XXH3_freeState(state);
      throw Error(path + ": read error");
    }
  }
  return finish_hash(state);
}

namespace {

std::unique_ptr<Parameterization> make_grid(Kind grid, int width, int height) {
  if (grid == Kind::Octahedral) return std::make_unique<OctahedralMap>(width);
  if (grid == Kind::HEALPix) return std::make_unique<HealpixMap>(width / 4);
  return std::make_unique<LatLongMap>(width, height, TexelGrid::Centre);
}

/// Exact solid angle of the texels of each row: per row for lat-long, constant for the equal-area grids.
std::vector<double> row_solid_angles(const Parameterization& grid, int height) {
  std::vector<double> omega(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) omega[std::size_t(y)] = grid.solid_angle(0.0, y, 1.0, y + 1.0);
  return omega;
}

std::shared_ptr<const StoredDistribution2D> make_distribution_2d(SamplingMethod method, const float* weights, int W,
                                                                 int H) {
  switch (method) {
    case SamplingMethod::Cdf:
      return std::make_shared<CdfDistribution2D>(weights, W, H);
    case SamplingMethod::Alias:
      return std::make_shared<AliasDistribution2D>(weights, W, H);
    case SamplingMethod::Hierarchical:
      return std::make_shared<HierarchicalDistribution2D>(weights, W, H);
  }
  throw Error("unknown sampling method");
}

/// The power of two that keeps weights with this sum and this smallest positive weight inside float's comfortable
/// range [2^-120, 2^120] (above subnormals, 2^8 below overflow for the sums of pyramids and CDFs): 1 for every
/// weight set already inside it, so real maps keep their absolute weights; else the sum brought down to 2^120, or
/// the smallest weight up towards 2^-120 as far as the sum allows.
double weight_scale(double sum, double smallest) {
  constexpr int kRange = 120;
  if (!(sum > 0.0) || !std::isfinite(sum)) return 1.0;
  if (sum > std::ldexp(1.0, kRange)) return std::ldexp(1.0, kRange - 1 - std::ilogb(sum));
  if (smallest >= std::ldexp(1.0, -kRange)) return 1.0;
  const int up = -kRange - std::ilogb(smallest) + 1, headroom = kRange - 1 - std::ilogb(sum);
  return std::ldexp(1.0, std::min(up, headroom));
}

/// The weights importance x exact texel solid angle of a W x H grid (value(i): importance of texel i, row-major), as
/// float, multiplied by weight_scale(). A distribution normalises its weights, so the scale changes nothing it
/// samples; without it, importance near float's subnormal range (or near FLT_MAX) would lose its precision (or
/// overflow) in the product, and small texels such as the polar rows would get weight 0.
template <class Value>
FloatBuffer texel_weights(const Value& value, const std::vector<double>& row_omega, int W, int H) {
  std::vector<double> row_sum(std::size_t(H), 0.0), row_min(std::size_t(H), HUGE_VAL);
  tbb::parallel_for(0, H, [&](int y) {
    double sum = 0.0, smallest = HUGE_VAL;
    for (int x = 0; x < W; ++x) {
      const double v = double(value(std::size_t(y) * W + x));
      sum += v;
      if (v > 0.0) smallest = std::min(smallest, v);
    }
    row_sum[std::size_t(y)] = sum * row_omega[std::size_t(y)];
    row_min[std::size_t(y)] = smallest * row_omega[std::size_t(y)];
  });
  double sum = 0.0;  // in row order: deterministic
  for (const double s : row_sum) sum += s;
  const double scale = weight_scale(sum, *std::min_element(row_min.begin(), row_min.end()));
  FloatBuffer w(std::size_t(W) * std::size_t(H));
  tbb::parallel_for(0, H, [&](int y) {
    const double omega = row_omega[std::size_t(y)] * scale;
    for (int x = 0; x < W; ++x) {
      const std::size_t i = std::size_t(y) * W + x;
      w[i] = static_cast<float>(double(value(i)) * omega);
    }
  });
  return w;
}

/// True when the map's texels are already the bake grid's texels (same kind, centre grid, no transform).
bool on_bake_grid(const EnvMap& map, Kind grid) {
  if (map.param->kind() != grid || !is_identity(map.to_world())) return false;
  if (grid == Kind::Octahedral) return map.image.width == map.image.height;
  if (grid == Kind::HEALPix) return true;  // its layout is fixed by N_side: any HEALPix map is a HEALPix grid
  return map.param->grid() == TexelGrid::Centre;
}

/// True when W x H is a valid size for `grid`: octahedral N x N, HEALPix 4 N_side x 3 N_side, lat-long any.
bool valid_grid_size(Kind grid, int W, int H) {
  if (grid == Kind::Octahedral) return W == H;
  if (grid == Kind::HEALPix) return W % 4 == 0 && std::int64_t(W) * 3 == std::int64_t(H) * 4;
  return true;
}

/// The rule valid_grid_size checks, for error messages.
const char* grid_size_rule(Kind grid) {
  return grid == Kind::HEALPix ? "a HEALPix grid must be 4 N_side x 3 N_side" : "an octahedral grid must be square";
}

/// The natural bake grid of a map that is not already on it: about as many texels as the source.
void natural_grid_size(Kind grid, double texels, int& W, int& H) {
  if (grid == Kind::Octahedral) {
    W = H = std::max(1, int(std::lround(std::sqrt(texels))));
  } else if (grid == Kind::HEALPix) {
    const int nside = std::max(1, int(std::lround(std::sqrt(texels / 12.0))));
    W = 4 * nside;
    H = 3 * nside;
  } else {
    H = std::max(1, int(std::lround(std::sqrt(texels / 2.0))));
    W = 2 * H;
  }
}

/// Scalar importance of one texel from its colour channels (alpha is coverage, not light).
struct ImportanceFunction {
  ImportanceMode mode;
  Vec3 weights;            // luminance weights of the working space
  std::vector<int> color;  // indices of the colour channels

  float operator()(const float* texel) const {
    double value = 0.0;
    if (color.size() >= 3 && mode == ImportanceMode::Luminance) {
      value = weights.x * positive(texel[color[0]]) + weights.y * positive(texel[color[1]]) +
              weights.z * positive(texel[color[2]]);
    } else if (mode == ImportanceMode::Max) {
      for (int c : color) value = std::max(value, positive(texel[c]));
    } else {  // average, or luminance of a one/two-channel image (its channels are already grey)
      for (int c : color) value += positive(texel[c]);
      value /= double(std::max<std::size_t>(1, color.size()));
    }
    return static_cast<float>(std::min(value, double(FLT_MAX)));
  }
  static double positive(float v) { return v > 0.0f ? double(std::min(v, FLT_MAX)) : 0.0; }
};

ImportanceFunction importance_function(const Image& image, ImportanceMode mode) {
  ImportanceFunction f{mode, luminance_weights("scene_linear"), {}};
  for (int c = 0; c < image.channels; ++c)
    if (c != image.alpha_channel) f.color.push_back(c);
  return f;
}

/// Max over each texel's 3x3 neighbourhood: the texels a bilinear lookup anywhere inside it may touch.
FloatBuffer dilate_3x3(const FloatBuffer& values, const Parameterization& grid, int W, int H) {
  FloatBuffer out(values.size());
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) {
      float m = values[std::size_t(y) * W + x];
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          int i = x + dx, j = y + dy;
          if ((dx || dy) && grid.resolve_tap(x, y, i, j)) m = std::max(m, values[std::size_t(j) * W + i]);
        }
      out[std::size_t(y) * W + x] = m;
    }
  });
  return out;
}

}  // namespace

void select_tables(const std::vector<std::string>& names, BakeOptions& options) {
  options.cdf = options.alias = options.hierarchical = options.compensated = options.sun = false;
  for (const std::string& name : names) {
    if (name == "compensated" || name == "sun") {
      (name == "sun" ? options.sun : options.compensated) = true;
      continue;
    }
    SamplingMethod method;
    try {
      method = parse_method(name);
    } catch (const Error&) {
      throw Error("unknown table '" + name + "' (cdf, alias, hierarchical, compensated, sun)");
    }
    (method == SamplingMethod::Cdf     ? options.cdf
     : method == SamplingMethod::Alias ? options.alias
                                       : options.hierarchical) = true;
  }
  if (!options.cdf && !options.alias && !options.hierarchical)
    throw Error("name at least one of cdf, alias, hierarchical");
}

EnvTables EnvTables::bake(const EnvMap& map, const BakeOptions& options, const std::string& source_path,
                          std::string source_hash) {
  if (options.grid != Kind::LatLong && options.grid != Kind::Octahedral && options.grid != Kind::HEALPix)
    throw Error(std::string("bake: unsupported grid '") + kind_name(options.grid) +
                "' (expected latlong, octahedral or healpix)");
  if (map.image.empty()) throw Error(source_path + ": empty image");
  const auto progress = [&](double f, const char* stage) {
    if (options.progress) options.progress(f, stage);
  };

  EnvTables t;
  t.mode_ = options.importance;
  t.conservative_ = options.conservative;
  t.grid_ = options.grid;
  t.source_path_ = source_path;
  t.source_hash_ = source_hash.empty() ? image_content_hash(map.image) : std::move(source_hash);
  t.source_to_world_ = map.to_world();

  // 1. The bake grid.
  const bool native = on_bake_grid(map, options.grid);
  int W = options.width, H = options.height;
  if (W <= 0 || H <= 0) {
    if (native) {
      W = map.image.width;
      H = map.image.height;
    } else {
      natural_grid_size(options.grid, double(map.image.texel_count()), W, H);
    }
  }
  if (!valid_grid_size(options.grid, W, H))
    throw Error(std::string("bake: ") + grid_size_rule(options.grid) + ", got " + std::to_string(W) + "x" +
                std::to_string(H));
  if (W > kMaxDistributionSize || H > kMaxDistributionSize)
    throw Error("bake: grid " + std::to_string(W) + "x" + std::to_string(H) + " is too large");
  const std::unique_ptr<Parameterization> grid = make_grid(options.grid, W, H);
  std::string resampled_from;
  const bool use_source = native && W == map.image.width && H == map.image.height;
  Image resampled;
  if (!use_source) {
    progress(0.0, "resampling onto the bake grid");
    ResampleOptions ro;
    ro.filter = Filter::Area;
    resampled = resample(map.ref(), *grid, identity3(), ro);
    resampled_from = map.param->describe();
  }
  const Image& radiance = use_source ? map.image : resampled;

  // 2. Scalar importance on the grid.
  progress(0.2, "importance");
  const ImportanceFunction importance_of = importance_function(radiance, options.importance);
  FloatBuffer importance(std::size_t(W) * std::size_t(H));
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) importance[std::size_t(y) * W + x] = importance_of(radiance.at(x, y));
  });

  // Optional lower importance resolution: area-filter the scalar map (solid-angle weighted).
  int TW = W, TH = H;
  if (options.importance_width > 0 && options.importance_height > 0 &&
      (options.importance_width != W || options.importance_height != H)) {
    TW = options.importance_width;
    TH = options.importance_height;
    if (TW > W || TH > H)
      throw Error("bake: --resolution " + std::to_string(TW) + "x" + std::to_string(TH) + " exceeds the bake grid " +
                  std::to_string(W) + "x" + std::to_string(H));
    if (!valid_grid_size(options.grid, TW, TH))
      throw Error(std::string("bake: importance resolution ") + std::to_string(TW) + "x" + std::to_string(TH) + ": " +
                  grid_size_rule(options.grid));
    Image scalar(W, H, 1);
    scalar.pixels = std::move(importance);
    const std::unique_ptr<Parameterization> coarse = make_grid(options.grid, TW, TH);
    ResampleOptions ro;
    ro.filter = Filter::Area;
    importance = resample(MapRef{scalar, *grid, identity3()}, *coarse, identity3(), ro).pixels.take();
  }
  t.grid_width_ = W;
  t.grid_height_ = H;
  t.width_ = TW;
  t.height_ = TH;
  const std::unique_ptr<Parameterization> table_grid = make_grid(options.grid, TW, TH);
  if (options.conservative) importance = dilate_3x3(importance, *table_grid, TW, TH);
  for (float& v : importance)
    v = static_cast<float>(ImportanceFunction::positive(v));  // resampling may leave -0 or tiny negatives
  t.importance_.adopt(std::move(importance));

  t.build_distributions(options);
  if (options.sun) {
    progress(0.9, "sun split");
    t.store_sun_splits();
  }
  t.descriptor_ = t.make_descriptor(&options);
  if (!resampled_from.empty()) {
    auto d = nlohmann::json::parse(t.descriptor_);
    d["bake"]["resampled_from"] = resampled_from;
    t.descriptor_ = d.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
  }
  progress(1.0, "done");
  return t;
}

void EnvTables::build_distributions(const BakeOptions& options) {
  const int W = width_, H = height_;
  const std::vector<double> row_omega = row_solid_angles(*make_grid(grid_, W, H), H);

  double total = 0.0;
  for (int y = 0; y < H; ++y) {
    double row = 0.0;
    for (int x = 0; x < W; ++x) row += importance_[std::size_t(y) * W + x];
    total += row * row_omega[y];
  }
  total_importance_ = total;

  const auto weights_of = [&](const auto& value) { return texel_weights(value, row_omega, W, H); };

  const bool wanted[3] = {options.cdf, options.alias, options.hierarchical};
  const SphericalDistribution* first = nullptr;  // every table lies on one grid: the others share its geometry
  const auto build_set = [&](const FloatBuffer& weights, int set) {
    for (int m = 0; m < 3; ++m) {
      if (!wanted[m]) continue;
      if (options.progress)
        options.progress(0.3 + 0.35 * set + 0.1 * m, m == 0   ? "cdf tables"
                                                     : m == 1 ? "alias tables"
                                                              : "hierarchical tables");
      std::shared_ptr<const StoredDistribution2D> d = make_distribution_2d(SamplingMethod(m), weights.data(), W, H);
      distributions_[set][m] = first ? std::make_unique<StoredTable>(*first, std::move(d))
                                     : std::make_unique<StoredTable>(grid_, std::move(d));
      if (!first) first = distributions_[set][m].get();
    }
  };

  const FloatBuffer weights = weights_of([&](std::size_t i) { return importance_[i]; });
  build_set(weights, 0);
  if (options.compensated) {
    if (!compensated_importance_is_zero()) {
      const double mean = total / kFourPi;  // solid-angle mean of the importance
      build_set(weights_of([&](std::size_t i) { return std::max(0.0, double(importance_[i]) - mean); }), 1);
    } else {
      for (int m = 0; m < 3; ++m)
        if (distributions_[0][m])
          distributions_[1][m] =
              std::make_unique<StoredTable>(*distributions_[0][m], distributions_[0][m]->stored_ptr());
    }
  }
  warnings_ = bake_warnings(options.compensated);
}

bool EnvTables::compensated_importance_is_zero() const {
  const double mean = total_importance_ / kFourPi;  // solid-angle mean of the importance
  return std::none_of(importance_.begin(), importance_.end(), [mean](float v) { return double(v) > mean; });
}

std::vector<TableWarning> EnvTables::bake_warnings(bool compensated) const {
  using Cause = TableWarning::Cause;
  std::vector<TableWarning> w;
  if (!(total_importance_ > 0.0)) {
    w.push_back({Cause::NoLight, "the map carries no light (all importance is zero): the tables sample uniformly"});
  } else {
    const int W = width_, H = height_;
    int zero_rows = 0;
    for (int y = 0; y < H; ++y)
      zero_rows += std::all_of(std::as_const(importance_).begin() + std::ptrdiff_t(y) * W,
                               std::as_const(importance_).begin() + std::ptrdiff_t(y + 1) * W,
                               [](float v) { return !(v > 0.0f); });
    if (zero_rows > 0)
      w.push_back({Cause::ZeroRows, std::to_string(zero_rows) + " all-zero rows: never sampled (pdf 0 there); their "
                                                                "conditional tables are uniform"});
    const SphericalDistribution* cdf = distributions_[0][0].get();
    if (cdf && cdf->distribution().unreachable_texels() > 0)
      w.push_back({Cause::UnreachableTexels, std::to_string(cdf->distribution().unreachable_texels()) +
                                                 " lit texels are below the float resolution of their CDF (cdf gives "
                                                 "them pdf 0; hierarchical and alias sample them)"});
  }
  if (compensated && compensated_importance_is_zero())
    w.push_back({Cause::CompensatedFallback,
                 "compensated importance max(f - mean, 0) is zero everywhere (a constant map): the compensated tables "
                 "are the plain ones"});
  return w;
}

std::vector<TableWarning> EnvTables::with_causes(const std::vector<std::string>& messages) const {
  const bool compensated =
      std::any_of(distributions_[1].begin(), distributions_[1].end(), [](const auto& d) { return d != nullptr; });
  const std::vector<TableWarning> found = bake_warnings(compensated);
  std::vector<TableWarning> w;
  for (std::size_t i = 0; i < messages.size(); ++i)
    w.push_back({found.size() == messages.size() ? found[i].cause : TableWarning::Cause::Other, messages[i]});
  return w;
}

const StoredTable* EnvTables::distribution(SamplingMethod method, bool compensated) const {
  return distributions_[compensated ? 1 : 0][static_cast<int>(method)].get();
}

void EnvTables::store_sun_splits() {
  sun_looked_for_ = true;
  std::shared_ptr<const SunSplit> first;
  for (int set = 0; set < 2; ++set)
    for (int m = 0; m < 3; ++m) {
      if (!distributions_[set][m]) continue;
      if (!first) {
        std::optional<SunSplit> split = SunSplit::make(*this, SamplingMethod(m), set == 1);
        if (!split) return;  // no sun: every split stays null
        first = std::make_shared<const SunSplit>(std::move(*split));
        sun_splits_[set][m] = first;
      } else {
        sun_splits_[set][m] = std::make_shared<const SunSplit>(first->with_method(*this, SamplingMethod(m), set == 1));
      }
    }
}

std::optional<std::shared_ptr<const SunSplit>> EnvTables::stored_sun_split(SamplingMethod method,
                                                                           bool compensated) const {
  if (!sun_looked_for_) return std::nullopt;
  const bool sun_found = std::any_of(sun_splits_.begin(), sun_splits_.end(), [](const auto& set) {
    return std::any_of(set.begin(), set.end(), [](const auto& split) { return split != nullptr; });
  });
  if (!sun_found) return std::shared_ptr<const SunSplit>();
  const auto& split = sun_splits_[compensated ? 1 : 0][static_cast<int>(method)];
  if (!split) return std::nullopt;
  return split;
}

std::vector<std::pair<std::string, std::size_t>> EnvTables::table_bytes() const {
  std::vector<std::pair<std::string, std::size_t>> out;
  out.emplace_back("importance", importance_.size() * sizeof(float));
  for (int set = 0; set < 2; ++set)
    for (int m = 0; m < 3; ++m)
      if (distributions_[set][m])
        out.emplace_back(table_name(SamplingMethod(m), set != 0), distributions_[set][m]->distribution().bytes());
  for (int set = 0; set < 2; ++set)
    for (int m = 0; m < 3; ++m)
      if (sun_splits_[set][m])
        out.emplace_back("sun-" + table_name(SamplingMethod(m), set != 0),
                         sun_splits_[set][m]->residual().distribution().bytes() +
                             sun_splits_[set][m]->sun_distribution().distribution().bytes());
  return out;
}

std::string EnvTables::make_descriptor(const BakeOptions* options) const {
  nlohmann::json d;
  d["format"] = "envkit sampling tables";
  d["version"] = kTableFormatVersion;
  d["grid"] = kind_name(grid_);
  d["width"] = width_;
  d["height"] = height_;
  d["grid_width"] = grid_width_;
  d["grid_height"] = grid_height_;
  d["importance"] = importance_name(mode_);
  d["conservative"] = conservative_;
  d["total_importance"] = total_importance_;
  d["source"] = {{"path", source_path_}, {"hash", source_hash_}};
  if (source_to_world_) {
    nlohmann::json m = nlohmann::json::array();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m.push_back((*source_to_world_)[r][c]);
    d["source"]["to_world"] = m;  // row-major
  }
  nlohmann::json methods = nlohmann::json::array(), compensated = nlohmann::json::array();
  for (int m = 0; m < 3; ++m) {
    if (distributions_[0][m]) methods.push_back(method_name(SamplingMethod(m)));
    if (distributions_[1][m]) compensated.push_back(method_name(SamplingMethod(m)));
  }
  d["methods"] = methods;
  d["compensated_methods"] = compensated;
  nlohmann::json warnings = nlohmann::json::array();
  for (const TableWarning& w : warnings_) warnings.push_back(w.message);
  d["warnings"] = warnings;
  if (sun_looked_for_) {  // for people reading the descriptor; loading reads the sun's own section
    d["sun"] = nullptr;
    for (const auto& set : sun_splits_)
      for (const auto& split : set)
        if (split && d["sun"].is_null()) {
          const SunEstimate& sun = split->sun();
          d["sun"] = {{"direction", {sun.direction.x, sun.direction.y, sun.direction.z}},
                      {"angular_radius_deg", sun.angular_radius * 180.0 / kPi},
                      {"power_share", sun.power_share},
                      {"texels", sun.texels},
                      {"clipped", sun.clipped}};
        }
  }
  if (options) {
    d["bake"] = {{"importance_resolution", {width_, height_}},
                 {"requested_grid", {options->width, options->height}},
                 {"conservative", options->conservative},
                 {"compensated", options->compensated},
                 {"sun", options->sun}};
  }
  // File names are bytes, not necessarily UTF-8: the descriptor shows U+FFFD for invalid bytes rather than failing.
  return d.dump(2, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::unique_ptr<StoredTable> make_table(Kind grid, int width, int height, std::span<const float> importance,
                                        SamplingMethod method) {
  if (!valid_grid_size(grid, width, height))
    throw Error(std::string("table: ") + grid_size_rule(grid) + ", got " + std::to_string(width) + "x" +
                std::to_string(height));
  if (importance.size() != std::size_t(width) * std::size_t(height))
    throw Error("table: " + std::to_string(importance.size()) + " importance values for a " + std::to_string(width) +
                "x" + std::to_string(height) + " grid");
  const std::vector<double> row_omega = row_solid_angles(*make_grid(grid, width, height), height);
  const FloatBuffer weights = texel_weights([&](std::size_t i) { return importance[i]; }, row_omega, width, height);
  return std::make_unique<StoredTable>(grid, make_distribution_2d(method, weights.data(), width, height));
}

}  // namespace envkit
