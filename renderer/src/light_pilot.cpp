// Strategy auto's pilot: each material's light technique (LightChoice) from a short measurement of every candidate
// at shading points the camera sees. See integrator.h ("auto") for the rule.
#include <envkit/render/integrator.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

namespace envkit::render {

namespace {

/// Camera rays on a kGrid x kGrid lattice of image positions find the pixels the pilot renders.
constexpr int kGrid = 96;
/// Pixels per material (evenly thinned from those the lattice finds).
constexpr int kPoints = 128;
/// First, every candidate draws kRepeats independent estimates at the shading point each pixel's lattice position
/// sees: a precise ranking of the candidates at a point.
constexpr int kRepeats = 32;
/// Then the best of them, if not MIS's own choice, and MIS's choice render each pixel kBatches times (independent
/// scramblings) at kBatchSpp samples, as the image renders a pixel: a batch's mean has the error of a pixel at
/// kBatchSpp spp, with what the pixel's samples gain from being one stratified sequence.
constexpr int kBatches = 4;
constexpr int kBatchSpp = 16;
/// A candidate replaces MIS's choice when its measured gain is this many standard errors above 0 (one-sided, about
/// 93% if the differences were normal): a lower bar misses fewer gains and takes more losses that are noise.
constexpr double kSignificance = 1.5;
/// A light sample drawn from a product table costs this much more than one from the plain table (the table's
/// choice and the refined descent), in units of one shadow ray and BSDF evaluation: BENCHMARKS.md, "The default: a
/// pilot per material".
constexpr double kProductDescentCost = 0.25;
/// relMSE's floor under the squared mean, in the image's units: the one the benchmarks and the report use, so that
/// dark points weigh as they do there.
constexpr double kRelMseFloor = 1e-2;
constexpr std::uint32_t kPilotSeed = 0x9e3779b9u;

/// A pixel the pilot renders: the lattice cell that found it (its sampler's seed, so that two cells in one image
/// pixel draw apart), the lattice position and the image pixel holding it.
struct PilotPixel {
  int cell_x, cell_y;
  double position_x, position_y;
  int x, y;
};

/// The first moments of n estimates of one colour channel.
struct Moments {
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  void add(double v) {
    sum += v;
    sum_sq += v * v;
    ++n;
  }
  double mean() const { return n > 0 ? sum / n : 0.0; }
  double variance() const { return n > 1 ? std::max(0.0, sum_sq / n - mean() * mean()) * n / (n - 1) : 0.0; }
};
/// Per channel (R, G, B): the images are judged by relMSE over every channel, so a channel that is dim under this
/// light (the blue of a warm interior) weighs as much as the others, which a luminance would hide.
using ChannelMoments = std::array<Moments, 3>;

/// Whether every corner of pixel (x, y) sees `material`.
bool pixel_inside(const Scene& scene, const Camera& camera, int x, int y, int material) {
  for (int c = 0; c < 4; ++c) {
    Hit hit;
    if (!scene.intersect(camera.generate(x + (c & 1), y + (c >> 1)), hit) || hit.material != material) return false;
  }
  return true;
}

/// Per scene material, the pixels of lattice positions whose camera ray first hits its front: those lying wholly on
/// it when there are any (a pixel across a silhouette adds the variance of its coverage, the same for every
/// candidate, which hides their differences), else all.
std::vector<std::vector<PilotPixel>> pilot_pixels(const Scene& scene, const Camera& camera) {
  std::vector<std::vector<PilotPixel>> inside(std::size_t(scene.material_count())), edge(inside.size());
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      const double x = (i + 0.5) * camera.width() / kGrid, y = (j + 0.5) * camera.height() / kGrid;
      const Ray ray = camera.generate(x, y);
      Hit hit;
      if (!scene.intersect(ray, hit)) continue;
      const SurfaceView view = surface_view(hit.geometric_normal, hit.shading_normal, -ray.direction);
      if (!(view.wo.z > 0.0)) continue;
      const PilotPixel pixel{i, j, x, y, int(x), int(y)};
      (pixel_inside(scene, camera, pixel.x, pixel.y, hit.material) ? inside : edge)[std::size_t(hit.material)]
          .push_back(pixel);
    }
  for (std::size_t m = 0; m < inside.size(); ++m)
    if (inside[m].empty()) inside[m] = std::move(edge[m]);
  return inside;
}

/// At most kPoints of `all`, evenly spaced in the lattice's order.
std::vector<PilotPixel> thinned(const std::vector<PilotPixel>& all) {
  const std::size_t n = std::min<std::size_t>(kPoints, all.size());
  std::vector<PilotPixel> pixels;
  for (std::size_t k = 0; k < n; ++k) pixels.push_back(all[k * all.size() / n]);
  return pixels;
}

/// scores[p x C + c]: pixel p's relative variance (of its batch means) under candidate c, as the images are judged
/// (relMSE: per channel the variance over the squared mean plus kRelMseFloor, the mean over every candidate since they
/// estimate the same value; averaged over the channels), times the candidate's cost per shading point.
std::vector<double> scores(const std::vector<ChannelMoments>& moments, const std::vector<LightChoice>& candidates,
                           SampleCounts n, int sun_samples) {
  const std::size_t count = candidates.size(), points = moments.size() / count;
  std::vector<double> out(moments.size(), 0.0);
  for (std::size_t p = 0; p < points; ++p)
    for (std::size_t ch = 0; ch < 3; ++ch) {
      double mean = 0.0;
      for (std::size_t c = 0; c < count; ++c) mean += moments[p * count + c][ch].mean() / double(count);
      for (std::size_t c = 0; c < count; ++c)
        out[p * count + c] += moments[p * count + c][ch].variance() / (mean * mean + kRelMseFloor) / 3.0;
    }
  for (std::size_t p = 0; p < points; ++p)
    for (std::size_t c = 0; c < count; ++c) {
      const LightChoice& k = candidates[c];
      out[p * count + c] *=
          1.0 + n.bsdf + n.light * (1.0 + (k.product ? kProductDescentCost : 0.0)) + (k.sun_apart ? sun_samples : 0);
    }
  return out;
}

/// The candidate to keep: `base` (MIS's choice) unless a candidate's mean score is lower by more than kSignificance
/// standard errors of the per-pixel differences, so that the technique changes only where a gain was measured; of
/// several such candidates, the one of the largest gain.
std::size_t pick(const std::vector<double>& scores, std::size_t count, std::size_t base) {
  const std::size_t points = scores.size() / count;
  std::size_t best = base;
  double best_gain = 0.0;
  for (std::size_t c = 0; c < count; ++c) {
    double sum = 0.0, sum_sq = 0.0;
    for (std::size_t p = 0; p < points; ++p) {
      const double d = scores[p * count + base] - scores[p * count + c];
      sum += d;
      sum_sq += d * d;
    }
    const double gain = sum / double(points);
    const double se =
        std::sqrt(std::max(0.0, sum_sq / double(points) - gain * gain) / std::max(double(points) - 1.0, 1.0));
    if (gain > kSignificance * se && gain > best_gain) {
      best = c;
      best_gain = gain;
    }
  }
  return best;
}

}  // namespace

void Integrator::choose_by_pilot(const Camera& camera) {
  const std::vector<std::vector<PilotPixel>> found = pilot_pixels(scene_, camera);
  std::vector<LightChoice> candidates = {{true, false}, {false, false}};
  if (sun_) candidates.insert(candidates.end(), {{true, true}, {false, true}});
  // The shading point a camera ray sees at image position (x, y), if it is `material`'s front.
  const auto shading_point = [&](double x, double y, int material) -> std::optional<ShadingPoint> {
    const Ray ray = camera.generate(x, y);
    Hit hit;
    if (!scene_.intersect(ray, hit) || hit.material != material) return std::nullopt;
    const SurfaceView v = surface_view(hit.geometric_normal, hit.shading_normal, -ray.direction);
    if (!(v.wo.z > 0.0)) return std::nullopt;
    return ShadingPoint{Scene::offset_origin(hit.position, v.ng), v.frame, v.ng, v.wo, scene_.material(material)};
  };
  const auto add = [](ChannelMoments& moments, const Vec3& e) {
    for (int ch = 0; ch < 3; ++ch) moments[std::size_t(ch)].add(std::isfinite(e[ch]) ? e[ch] : 0.0);
  };
  // kRepeats independent estimates at the pixel's lattice position.
  const auto at_point = [&](const PilotPixel& px, int material, std::size_t c, LightChoice choice) {
    ChannelMoments moments;
    const std::optional<ShadingPoint> x = shading_point(px.position_x, px.position_y, material);
    Sampler sampler(kPilotSeed, px.cell_x, px.cell_y);
    for (int r = 0; r < kRepeats && x; ++r) {
      sampler.start_sample(std::uint32_t(c * kRepeats + r));
      add(moments, direct_mis_with(*x, sampler, choice));
    }
    return moments;
  };
  // kBatches means of kBatchSpp samples of the pixel's direct light at `material`, drawn as the render draws them
  // (the jitter, then the shading point's samples). Over a pixel a lobe's axis moves, and with it the product table
  // a sample draws from, while the plain table stays: the batches keep that difference, which one shading point's
  // independent estimates hide. Samples that see another material or its back count 0. Every candidate gets the
  // same scramblings: their batches see the same positions in the pixel.
  const auto over_pixel = [&](const PilotPixel& px, int material, std::size_t, LightChoice choice) {
    ChannelMoments moments;
    for (int b = 0; b < kBatches; ++b) {
      Sampler sampler(hash_combine(kPilotSeed, std::uint32_t(b)), px.cell_x, px.cell_y);
      Vec3 sum(0, 0, 0);
      for (int s = 0; s < kBatchSpp; ++s) {
        sampler.start_sample(std::uint32_t(s));
        const Vec2 jitter = sampler.next_2d();
        if (const std::optional<ShadingPoint> x = shading_point(px.x + jitter.x, px.y + jitter.y, material))
          sum += direct_mis_with(*x, sampler, choice);
      }
      add(moments, sum / double(kBatchSpp));
    }
    return moments;
  };
  // moments[p x C + c]: each pixel's slots are its own, so the sums do not depend on the threads.
  const auto measure = [&](const std::vector<PilotPixel>& pixels, int material, const std::vector<LightChoice>& set,
                           const auto& estimate) {
    std::vector<ChannelMoments> moments(pixels.size() * set.size());
    tbb::parallel_for(std::size_t(0), pixels.size(), [&](std::size_t p) {
      for (std::size_t c = 0; c < set.size(); ++c)
        moments[p * set.size() + c] = estimate(pixels[p], material, c, set[c]);
    });
    return moments;
  };
  for (int m = 0; m < scene_.material_count(); ++m) {
    const Material& material = scene_.material(m);
    const std::vector<PilotPixel> pixels = thinned(found[std::size_t(m)]);
    if (material.is_pure_delta() || pixels.empty()) continue;
    const SampleCounts n = counts(material);
    const LightChoice mis_choice{false, sun_ && takes_sun_samples(material)};
    const std::size_t base =
        std::size_t(std::find(candidates.begin(), candidates.end(), mis_choice) - candidates.begin());
    const std::vector<ChannelMoments> points = measure(pixels, m, candidates, at_point);
    const std::size_t best = pick(scores(points, candidates, n, options_.sun_samples), candidates.size(), base);
    choices_[std::size_t(m)] = mis_choice;
    if (best == base) continue;
    // The gain at points, confirmed over pixels.
    const std::vector<LightChoice> pair = {mis_choice, candidates[best]};
    const std::vector<ChannelMoments> batches = measure(pixels, m, pair, over_pixel);
    choices_[std::size_t(m)] = pair[pick(scores(batches, pair, n, options_.sun_samples), pair.size(), 0)];
  }
}

}  // namespace envkit::render
