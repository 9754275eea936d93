#include <envkit/core/error.h>
#include <envkit/resample/filter.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>

namespace envkit {

std::string filter_name(Filter filter) {
  switch (filter) {
    case Filter::Nearest:
      return "nearest";
    case Filter::Bilinear:
      return "bilinear";
    case Filter::Bicubic:
      return "bicubic";
    case Filter::Area:
      return "area";
  }
  return "area";
}

Filter parse_filter(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (n == "nearest" || n == "point") return Filter::Nearest;
  if (n == "bilinear" || n == "linear") return Filter::Bilinear;
  if (n == "bicubic" || n == "cubic" || n == "catmull-rom") return Filter::Bicubic;
  if (n == "area" || n == "box" || n == "flux") return Filter::Area;
  throw Error("unknown filter '" + name + "' (expected nearest, bilinear, bicubic or area)");
}

TexelSource::TexelSource(const Image& image, const Parameterization& param) : image_(image), param_(param) {
  if (image.width != param.width() || image.height != param.height())
    throw Error("image size " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                " does not match the parameterization (" + param.describe() + ")");
  if (param.tap_cell() > 0) cell_multiple_ = ~std::uint64_t(0) / static_cast<std::uint64_t>(param.tap_cell()) + 1;
  // Only maps with blank regions (crosses, balls, paraboloids) need a coverage mask.
  if (param.has_blank_texels()) {
    covered_.assign(image.texel_count(), 0);
    tbb::parallel_for(0, image.height, [&](int j) {
      for (int i = 0; i < image.width; ++i)
        covered_[static_cast<std::size_t>(j) * image.width + i] = param.texel_solid_angle(i, j) > 0.0;
    });
    if (std::all_of(covered_.begin(), covered_.end(), [](unsigned char c) { return c != 0; })) covered_.clear();
  }
}

bool TexelSource::resolve(int anchor_i, int anchor_j, int& i, int& j) const {
  return param_.resolve(anchor_i, anchor_j, i, j) && covered(static_cast<std::size_t>(j) * image_.width + i);
}

namespace {
// Catmull-Rom weights for the four taps around fractional offset t in [0, 1).
void catmull_rom(double t, double w[4]) {
  const double t2 = t * t, t3 = t2 * t;
  w[0] = 0.5 * (-t3 + 2 * t2 - t);
  w[1] = 0.5 * (3 * t3 - 5 * t2 + 2);
  w[2] = 0.5 * (-3 * t3 + 4 * t2 + t);
  w[3] = 0.5 * (t3 - t2);
}
}  // namespace

int TexelSource::taps(Vec2 p, Filter filter, Tap* out) const {
  const int W = image_.width, H = image_.height;
  // The common case first: four covered taps inside the image on one chart need neither resolving nor renormalising.
  if (filter == Filter::Bilinear && interior_bilinear_taps(p, out)) return 4;
  const int ai = std::clamp(static_cast<int>(std::floor(p.x)), 0, W - 1);
  const int aj = std::clamp(static_cast<int>(std::floor(p.y)), 0, H - 1);
  int count = 0;
  double total = 0.0;
  auto add = [&](int i, int j, double w) {
    if (w == 0.0 || !resolve(ai, aj, i, j)) return;
    out[count++] = Tap{static_cast<std::size_t>(j) * W + i, static_cast<float>(w)};
    total += w;
  };
  if (filter == Filter::Nearest) {
    add(ai, aj, 1.0);
  } else {
    const double fx = p.x - 0.5, fy = p.y - 0.5;
    const int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
    const double tx = fx - i0, ty = fy - j0;
    if (filter == Filter::Bicubic) {
      double wx[4], wy[4];
      catmull_rom(tx, wx);
      catmull_rom(ty, wy);
      for (int b = 0; b < 4; ++b)
        for (int a = 0; a < 4; ++a) add(i0 - 1 + a, j0 - 1 + b, wx[a] * wy[b]);
    } else {
      add(i0, j0, (1 - tx) * (1 - ty));
      add(i0 + 1, j0, tx * (1 - ty));
      add(i0, j0 + 1, (1 - tx) * ty);
      add(i0 + 1, j0 + 1, tx * ty);
    }
  }
  // Renormalise over the taps that hold data. (Catmull-Rom weights can be negative, but they sum to 1 over a
  // full footprint; a sum near zero means almost nothing covered.)
  if (count == 0 || std::abs(total) < 1e-6) return 0;
  const float scale = static_cast<float>(1.0 / total);
  for (int k = 0; k < count; ++k) out[k].weight *= scale;
  return count;
}

bool TexelSource::sample(Vec2 p, Filter filter, float* out) const {
  const int C = image_.channels;
  std::fill(out, out + C, 0.0f);
  Tap t[16];
  const int n = taps(p, filter, t);
  if (n == 0) return false;
  for (int k = 0; k < n; ++k) {
    const float* px = image_.pixels.data() + t[k].index * C;
    for (int c = 0; c < C; ++c) out[c] += t[k].weight * px[c];
  }
  if (filter == Filter::Bicubic)
    for (int c = 0; c < C; ++c) out[c] = std::max(out[c], 0.0f);
  return true;
}

}  // namespace envkit
