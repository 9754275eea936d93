#include "sphere_pictures.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <envkit/sampling/sampler.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace envkit::render::cli {

namespace {

/// Points per side of a texel at which density_picture() averages the pdf.
constexpr int kPdfPoints = 4;

double luminance(const float* rgb) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

Vec3 texel_direction(const LatLongMap& map, int x, int y) {
  Vec3 d;
  map.to_direction(Vec2(x + 0.5, y + 0.5), d);
  return d;
}

void set_rgb(float* px, const Vec3& v) {
  for (int c = 0; c < 3; ++c) px[c] = std::isfinite(v[c]) ? float(v[c]) : 0.0f;
}

std::pair<int, int> texel_of(const LatLongMap& map, const Vec3& d) {
  const Vec2 p = map.to_image(d);
  return {std::clamp(int(p.x), 0, map.width() - 1), std::clamp(int(p.y), 0, map.height() - 1)};
}

}  // namespace

SpherePictures sphere_pictures(const LatLongMap& map, const PointView& point, const EnvironmentLight& light) {
  const int W = map.width(), H = map.height();
  SpherePictures p{Image(W, H, 3), Image(W, H, 3), Image(W, H, 3)};
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Vec3 d = texel_direction(map, x, y);
      const Vec3 f_cos = point.material->eval(point.wo_local, point.frame.to_local(d));
      const Vec3 radiance = light.radiance(d);
      set_rgb(p.brdf_cos.at(x, y), f_cos);
      set_rgb(p.lighting.at(x, y), radiance);
      // The product of the stored floats, so that the product picture is exactly the texel-wise product.
      const float* a = p.brdf_cos.at(x, y);
      const float* b = p.lighting.at(x, y);
      float* out = p.product.at(x, y);
      for (int c = 0; c < 3; ++c) out[c] = a[c] * b[c];
    }
  for (Image* image : {&p.brdf_cos, &p.lighting, &p.product}) image->channel_names = {"R", "G", "B"};
  return p;
}

StrategySamples draw_samples(const Integrator::StrategyDistribution& strategy, const LatLongMap& map, std::size_t n,
                             std::uint32_t seed) {
  StrategySamples s;
  s.n = n;
  s.texel_counts.assign(std::size_t(map.width()) * map.height(), 0.0);
  OwenSobolSampler sampler(seed, 0, 0);
  for (std::size_t i = 0; i < n; ++i) {
    sampler.start_sample(std::uint32_t(i));
    const Vec2 u = sampler.next_2d();
    const Integrator::StrategyDraw d = strategy.sample(u, sampler.next_1d());
    if (!d.is_delta && !(d.pdf > 0.0)) {
      ++s.none;
      continue;
    }
    if (s.directions.size() < kMaxDirections) s.directions.push_back(d.direction);
    if (d.is_delta) {
      ++s.delta;
      continue;
    }
    const auto [x, y] = texel_of(map, d.direction);
    s.texel_counts[std::size_t(y) * map.width() + x] += 1.0;
  }
  return s;
}

Image density_picture(const LatLongMap& map, const StrategySamples& samples,
                      const Integrator::StrategyDistribution& strategy) {
  const int W = map.width(), H = map.height();
  Image image(W, H, 3);
  tbb::parallel_for(0, H, [&](int y) {
    const double omega = map.solid_angle(0.0, y, 1.0, y + 1.0);
    for (int x = 0; x < W; ++x) {
      // The pdf's mean over the texel: kPdfPoints^2 sub-texels, each weighed by its solid angle.
      double mass = 0.0;
      for (int j = 0; j < kPdfPoints; ++j)
        for (int i = 0; i < kPdfPoints; ++i) {
          const double x0 = x + double(i) / kPdfPoints, y0 = y + double(j) / kPdfPoints;
          const double x1 = x0 + 1.0 / kPdfPoints, y1 = y0 + 1.0 / kPdfPoints;
          Vec3 d;
          map.to_direction(Vec2(0.5 * (x0 + x1), 0.5 * (y0 + y1)), d);
          mass += strategy.pdf(d) * map.solid_angle(x0, y0, x1, y1);
        }
      const double count = samples.texel_counts[std::size_t(y) * W + x];
      float* px = image.at(x, y);
      px[0] = samples.n > 0 ? float(count / (double(samples.n) * omega)) : 0.0f;
      px[1] = float(mass / omega);
      px[2] = 0.0f;
    }
  });
  image.channel_names = {"R", "G", "B"};
  return image;
}

Image display_picture(const Image& linear) {
  double sum = 0.0, max_y = 0.0;
  for (int y = 0; y < linear.height; ++y)
    for (int x = 0; x < linear.width; ++x) {
      const double Y = luminance(linear.at(x, y));
      sum += Y;
      max_y = std::max(max_y, Y);
    }
  const double mean = sum / double(std::max<std::size_t>(linear.texel_count(), 1));
  const double top = mean > 0.0 ? std::log1p(max_y / mean) : 0.0;
  Image out(linear.width, linear.height, 3);
  for (int y = 0; y < linear.height; ++y)
    for (int x = 0; x < linear.width; ++x) {
      const float* in = linear.at(x, y);
      const double Y = luminance(in);
      const double scale = Y > 0.0 && top > 0.0 ? std::log1p(Y / mean) / top / Y : 0.0;
      for (int c = 0; c < 3; ++c) out.at(x, y)[c] = float(std::clamp(in[c] * scale, 0.0, 1.0));
    }
  out.channel_names = {"R", "G", "B"};
  return out;
}

Image dotted_picture(const Image& display, const LatLongMap& map, const std::vector<Vec3>& directions) {
  Image out = display;
  for (std::size_t i = 0; i < std::size_t(out.texel_count()) * 3; ++i) out.pixels.data()[i] *= 0.4f;
  const int dot = std::max(1, map.width() / 256 + (map.width() >= 256 ? 1 : 0));
  for (const Vec3& d : directions) {
    const auto [x, y] = texel_of(map, d);
    for (int dy = 0; dy < dot; ++dy)
      for (int dx = 0; dx < dot; ++dx) {
        float* px = out.at(std::min(x + dx, out.width - 1), std::min(y + dy, out.height - 1));
        px[0] = 1.0f;
        px[1] = 0.1f;
        px[2] = 0.05f;
      }
  }
  return out;
}

Image compose_figure(const std::vector<Panel>& panels, int columns, bool* labelled) {
  constexpr int kGap = 4, kStrip = 22;
  const int W = panels.empty() ? 1 : panels[0].image->width, H = panels.empty() ? 1 : panels[0].image->height;
  const int rows = int((panels.size() + std::size_t(columns) - 1) / std::size_t(columns));
  const int font_size = W >= 384 ? 16 : 13;
  Image figure(columns * W + (columns + 1) * kGap, rows * (H + kStrip) + (rows + 1) * kGap, 3);
  std::fill(figure.pixels.data(), figure.pixels.data() + figure.texel_count() * 3, 0.06f);
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const int x0 = kGap + int(i % std::size_t(columns)) * (W + kGap);
    const int y0 = kGap + int(i / std::size_t(columns)) * (H + kStrip + kGap) + kStrip;
    for (int y = 0; y < H; ++y) std::copy_n(panels[i].image->at(0, y), 3 * W, figure.at(x0, y0 + y));
  }
  // The labels, drawn into the figure's own pixels.
  OIIO::ImageBuf buffer(OIIO::ImageSpec(figure.width, figure.height, 3, OIIO::TypeDesc::FLOAT), figure.pixels.data());
  const float white[3] = {0.9f, 0.9f, 0.9f};
  *labelled = true;
  std::string font;
  for (std::size_t i = 0; i < panels.size() && *labelled; ++i) {
    const int x = kGap + int(i % std::size_t(columns)) * (W + kGap) + 4;
    const int y = kGap + int(i / std::size_t(columns)) * (H + kStrip + kGap) + kStrip - 6;
    const auto draw = [&](const std::string& name) {
      return OIIO::ImageBufAlgo::render_text(buffer, x, y, panels[i].label, font_size, name, white);
    };
    if (draw(font)) continue;
    if (font.empty() && draw("DejaVuSans")) {
      font = "DejaVuSans";
      continue;
    }
    *labelled = false;
  }
  figure.channel_names = {"R", "G", "B"};
  return figure;
}

}  // namespace envkit::render::cli
