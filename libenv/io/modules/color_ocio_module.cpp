// envkit's OpenColorIO module (libenvkit_ocio.so): the colour functions of envkit/io/color.h behind the ColorBackend
// interface of libenv/io/src/color_backend.h. libenv loads it with dlopen on the first question its table of the
// shipped config cannot answer (libenv/io/src/color.cpp), so runs that never convert a colour never load OpenColorIO.
#include <OpenColorIO/OpenColorIO.h>
#include <envkit/core/error.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>

#include "color_backend.h"

namespace OCIO = OCIO_NAMESPACE;

namespace envkit {
namespace {

std::string env_value(const char* name) {
  const char* value = std::getenv(name);
  return value ? value : "";
}

/// OCIO messages may span lines; envkit errors are one line.
std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  std::replace(text.begin(), text.end(), '\r', ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

// ---- the active config ---------------------------------------------------------------------------------

struct ActiveConfig {
  OCIO::ConstConfigRcPtr config;
  std::string source;  // for messages
  std::string key;     // the environment it was loaded for
};

std::string shipped_config_path() {
  std::error_code ec;
#ifdef ENVKIT_OCIO_INSTALL_CONFIG
  if (std::filesystem::exists(ENVKIT_OCIO_INSTALL_CONFIG, ec)) return ENVKIT_OCIO_INSTALL_CONFIG;
#endif
#ifdef ENVKIT_OCIO_BUILD_CONFIG
  if (std::filesystem::exists(ENVKIT_OCIO_BUILD_CONFIG, ec)) return ENVKIT_OCIO_BUILD_CONFIG;
#endif
  return "";
}

OCIO::ConstConfigRcPtr load_config(const std::string& path, const std::string& shown, const std::string& hint) {
  try {
    return OCIO::Config::CreateFromFile(path.c_str());
  } catch (const OCIO::Exception& e) {
    throw Error(shown + ": " + one_line(e.what()) + hint);
  }
}

std::shared_ptr<const ActiveConfig> load_active(const std::string& key) {
  auto active = std::make_shared<ActiveConfig>();
  active->key = key;
  if (const std::string ocio = env_value("OCIO"); !ocio.empty()) {
    active->source = "$OCIO=" + ocio;
    active->config = load_config(ocio, active->source, "; unset OCIO to use envkit's built-in config");
  } else if (const std::string own = env_value("ENVKIT_OCIO_CONFIG"); !own.empty()) {
    active->source = own;
    active->config = load_config(own, "$ENVKIT_OCIO_CONFIG=" + own, "");
  } else {
    const std::string shipped = shipped_config_path();
    if (shipped.empty()) {
      std::string looked;
#ifdef ENVKIT_OCIO_INSTALL_CONFIG
      looked += std::string(ENVKIT_OCIO_INSTALL_CONFIG) + " ";
#endif
#ifdef ENVKIT_OCIO_BUILD_CONFIG
      looked += std::string(ENVKIT_OCIO_BUILD_CONFIG) + " ";
#endif
      throw Error("envkit's OCIO config not found (looked for " + one_line(looked) +
                  "); set OCIO or ENVKIT_OCIO_CONFIG to an OCIO config file");
    }
    active->source = shipped;
    active->config = load_config(shipped, shipped, "");
  }
  return active;
}

/// The config for the current environment; reloaded when $OCIO or $ENVKIT_OCIO_CONFIG change.
std::shared_ptr<const ActiveConfig> active_config() {
  static std::mutex mutex;
  static std::shared_ptr<const ActiveConfig> current;
  const std::string key = env_value("OCIO") + '\n' + env_value("ENVKIT_OCIO_CONFIG");
  std::lock_guard lock(mutex);
  if (!current || current->key != key) current = load_active(key);
  return current;
}

// ---- names -----------------------------------------------------------------------------------------------

/// Spellings of envkit's standard spaces in other common configs (ACES studio/cg configs, OCIO's own).
const std::map<std::string, std::vector<std::string>>& synonyms() {
  static const std::map<std::string, std::vector<std::string>> table = {
      {"lin_rec709", {"Linear Rec.709 (sRGB)", "Utility - Linear - sRGB", "Utility - Linear - Rec.709", "lin_srgb"}},
      {"srgb",
       {"sRGB - Texture", "sRGB Encoded Rec.709 (sRGB)", "Utility - sRGB - Texture", "srgb_tx",
        "Input - Generic - sRGB - Texture", "srgb_texture"}},
      {"rec709", {"Camera Rec.709", "Utility - Rec.709 - Camera", "rec709_camera"}},
      {"acescg", {"ACES - ACEScg", "lin_ap1"}},
      {"aces2065-1", {"ACES - ACES2065-1", "lin_ap0", "aces_interchange"}},
      {"raw", {"Utility - Raw", "data"}},
      {"cie_xyz_d65", {"CIE-XYZ-D65", "cie_xyz_d65_interchange"}},
      {"lin_p3d65", {"Linear P3-D65", "Utility - Linear - P3-D65"}},
      {"lin_rec2020", {"Linear Rec.2020", "Utility - Linear - Rec.2020"}},
  };
  return table;
}

/// Canonical colour-space name, or "" when the config does not know it.
std::string find_colorspace(const OCIO::Config& config, const std::string& name) {
  const auto lookup = [&config](const std::string& n) -> std::string {
    const char* canonical = config.getCanonicalName(n.c_str());
    if (canonical && *canonical && config.getColorSpace(canonical)) return canonical;
    return "";
  };
  if (std::string found = lookup(name); !found.empty()) return found;
  if (auto it = synonyms().find(lower(name)); it != synonyms().end())
    for (const std::string& alt : it->second)
      if (std::string found = lookup(alt); !found.empty()) return found;
  return "";
}

std::vector<std::string> active_names(const OCIO::Config& config) {
  std::vector<std::string> names;
  const int n = config.getNumColorSpaces(OCIO::SEARCH_REFERENCE_SPACE_ALL, OCIO::COLORSPACE_ACTIVE);
  for (int i = 0; i < n; ++i)
    names.emplace_back(config.getColorSpaceNameByIndex(OCIO::SEARCH_REFERENCE_SPACE_ALL, OCIO::COLORSPACE_ACTIVE, i));
  return names;
}

std::string require_colorspace(const ActiveConfig& active, const std::string& name) {
  std::string found = find_colorspace(*active.config, name);
  if (found.empty())
    throw Error("unknown colour space '" + name + "' in OCIO config " + active.source +
                "; valid colour spaces: " + join(active_names(*active.config)));
  return found;
}

std::string require_working_space(const ActiveConfig& active) {
  std::string found = find_colorspace(*active.config, OCIO::ROLE_SCENE_LINEAR);
  if (found.empty()) throw Error("OCIO config " + active.source + " has no scene_linear role");
  return found;
}

// ---- pixel processing ------------------------------------------------------------------------------------

OCIO::ConstCPUProcessorRcPtr cpu_of(const OCIO::ConstProcessorRcPtr& processor) {
  return processor->getOptimizedCPUProcessor(OCIO::BIT_DEPTH_F32, OCIO::BIT_DEPTH_F32, OCIO::OPTIMIZATION_DEFAULT);
}

/// Finite output for finite input: overflow to +/-inf is clamped, NaN becomes 0.
inline float sanitize(float v) {
  if (std::isnan(v)) return 0.0f;
  return std::clamp(v, -FLT_MAX, FLT_MAX);
}

std::vector<int> colour_channel_indices(const Image& image) {
  std::vector<int> idx;
  for (int c = 0; c < image.channels; ++c)
    if (c != image.alpha_channel) idx.push_back(c);
  if (idx.size() != 1 && idx.size() != 3)
    throw Error("colour conversion needs 1 (Y) or 3 (RGB) colour channels, the image has " +
                std::to_string(idx.size()));
  return idx;
}

/// Runs `cpu` over the colour channels of `image` (alpha untouched), then `post` on each RGB triple.
/// Colour channels are gathered into packed RGB blocks of whole rows, processed in parallel.
template <class Post>
void apply_to_colour(Image& image, const OCIO::CPUProcessor& cpu, const double luma[3], Post post) {
  if (image.empty()) return;
  if (image.pixels.size() != image.texel_count() * static_cast<std::size_t>(image.channels))
    throw Error("colour conversion: pixel buffer size does not match the image dimensions");
  const std::vector<int> idx = colour_channel_indices(image);
  const bool grey = idx.size() == 1;
  const int width = image.width;
  const int rows_per_block = std::max(1, 16384 / std::max(1, width));
  tbb::parallel_for(tbb::blocked_range<int>(0, image.height, rows_per_block), [&](const tbb::blocked_range<int>& r) {
    const std::size_t texels = static_cast<std::size_t>(width) * static_cast<std::size_t>(r.size());
    std::vector<float> rgb(texels * 3);
    float* base = image.at(0, r.begin());
    const auto nc = static_cast<std::size_t>(image.channels);
    for (std::size_t t = 0; t < texels; ++t)
      for (int k = 0; k < 3; ++k) rgb[3 * t + k] = base[t * nc + static_cast<std::size_t>(grey ? idx[0] : idx[k])];
    OCIO::PackedImageDesc desc(rgb.data(), width, static_cast<long>(r.size()), 3);
    cpu.apply(desc);
    for (std::size_t t = 0; t < texels; ++t) {
      float* v = &rgb[3 * t];
      post(v);
      if (grey) {
        base[t * nc + static_cast<std::size_t>(idx[0])] =
            sanitize(static_cast<float>(luma[0] * v[0] + luma[1] * v[1] + luma[2] * v[2]));
      } else {
        for (int k = 0; k < 3; ++k) base[t * nc + static_cast<std::size_t>(idx[k])] = sanitize(v[k]);
      }
    }
  });
}

void luma_of(const OCIO::Config& config, double luma[3]) {
  config.getDefaultLumaCoefs(luma);
  const double sum = luma[0] + luma[1] + luma[2];
  if (!(sum > 0.0) || !std::isfinite(sum)) {
    luma[0] = luma[1] = luma[2] = 1.0 / 3.0;
  } else {
    for (int k = 0; k < 3; ++k) luma[k] /= sum;
  }
}

std::vector<std::string> views_of(const OCIO::Config& config, const std::string& display) {
  std::vector<std::string> views;
  const int n = config.getNumViews(display.c_str());
  for (int i = 0; i < n; ++i) views.emplace_back(config.getView(display.c_str(), i));
  return views;
}

std::vector<std::string> displays_of(const OCIO::Config& config) {
  std::vector<std::string> displays;
  for (int i = 0; i < config.getNumDisplays(); ++i) displays.emplace_back(config.getDisplay(i));
  return displays;
}

/// OpenColorIO behind envkit's colour functions; stateless apart from the active config's cache.
class OcioColorBackend final : public detail::ColorBackend {
 public:
  std::string working_space() const override { return require_working_space(*active_config()); }

  std::string config_source() const override { return active_config()->source; }

  std::vector<std::string> colorspace_names() const override { return active_names(*active_config()->config); }

  std::string canonical_colorspace(const std::string& name) const override {
    return require_colorspace(*active_config(), name);
  }

  bool is_data_colorspace(const std::string& name) const override {
    const auto active = active_config();
    return active->config->getColorSpace(require_colorspace(*active, name).c_str())->isData();
  }

  void convert_colorspace(Image& image, const std::string& from, const std::string& to) const override {
    const auto active = active_config();
    const std::string src = require_colorspace(*active, from);
    const std::string dst = require_colorspace(*active, to);
    if (src == dst || image.empty()) return;
    OCIO::ConstProcessorRcPtr processor;
    try {
      processor = active->config->getProcessor(src.c_str(), dst.c_str());
    } catch (const OCIO::Exception& e) {
      throw Error("cannot convert colour from '" + src + "' to '" + dst + "': " + one_line(e.what()));
    }
    if (processor->isNoOp()) return;
    double luma[3];
    luma_of(*active->config, luma);
    apply_to_colour(image, *cpu_of(processor), luma, [](float*) {});
  }

  void decode_gamma(Image& image, double gamma) const override {
    if (!(gamma > 0.0) || !std::isfinite(gamma))
      throw Error("decode_gamma: gamma must be positive, got " + std::to_string(gamma));
    if (gamma == 1.0 || image.empty()) return;
    const auto active = active_config();
    auto exponent = OCIO::ExponentTransform::Create();
    const double value[4] = {gamma, gamma, gamma, 1.0};
    exponent->setValue(value);
    exponent->setNegativeStyle(OCIO::NEGATIVE_CLAMP);
    double luma[3];
    luma_of(*active->config, luma);
    apply_to_colour(image, *cpu_of(active->config->getProcessor(exponent)), luma, [](float*) {});
  }

  Vec3 luminance_weights(const std::string& colorspace) const override {
    const auto active = active_config();
    const std::string src = require_colorspace(*active, colorspace);
    if (active->config->getColorSpace(src.c_str())->isData())
      throw Error("colour space '" + src + "' holds data, not colour: it has no luminance");
    const std::string dst = require_working_space(*active);
    double luma[3];
    active->config->getDefaultLumaCoefs(luma);
    // The three primaries as seen in the working space; their luminance is luma . primary.
    float primaries[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    const auto cpu = cpu_of(active->config->getProcessor(src.c_str(), dst.c_str()));
    OCIO::PackedImageDesc desc(primaries, 3, 1, 3);
    cpu->apply(desc);
    Vec3 w;
    for (int p = 0; p < 3; ++p) {
      const double y = luma[0] * primaries[3 * p] + luma[1] * primaries[3 * p + 1] + luma[2] * primaries[3 * p + 2];
      w[p] = std::isfinite(y) ? y : 0.0;
    }
    return w;
  }

  std::vector<std::string> display_names() const override { return displays_of(*active_config()->config); }

  std::vector<std::string> view_names(const std::string& display) const override {
    const auto active = active_config();
    const std::vector<std::string> displays = displays_of(*active->config);
    if (std::find(displays.begin(), displays.end(), display) == displays.end())
      throw Error("unknown display '" + display + "' in OCIO config " + active->source +
                  "; valid displays: " + join(displays));
    return views_of(*active->config, display);
  }

  void encode_for_display(Image& image, const std::string& display, const std::string& view) const override {
    const auto active = active_config();
    const std::vector<std::string> views = view_names(display);
    if (std::find(views.begin(), views.end(), view) == views.end())
      throw Error("unknown view '" + view + "' for display '" + display + "' in OCIO config " + active->source +
                  "; valid views: " + join(views));
    const std::string src = require_working_space(*active);
    OCIO::ConstProcessorRcPtr processor;
    try {
      processor = active->config->getProcessor(src.c_str(), display.c_str(), view.c_str(), OCIO::TRANSFORM_DIR_FORWARD);
    } catch (const OCIO::Exception& e) {
      throw Error("cannot encode for display '" + display + "' view '" + view + "': " + one_line(e.what()));
    }
    double luma[3];
    luma_of(*active->config, luma);
    apply_to_colour(image, *cpu_of(processor), luma, [](float* v) {
      for (int k = 0; k < 3; ++k) v[k] = std::isnan(v[k]) ? 0.0f : std::clamp(v[k], 0.0f, 1.0f);
    });
  }
};

}  // namespace
}  // namespace envkit

extern "C" __attribute__((visibility("default"))) const envkit::detail::ColorBackend* envkit_color_backend_v1() {
  static const envkit::OcioColorBackend backend;
  return &backend;
}
