// Strategy auto's pilot: each material's light technique (LightChoice) from a short measurement of every candidate
// at shading points the camera sees. See integrator.h ("auto") for the rule.
#include <envkit/render/integrator.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace envkit::render {

namespace {

/// Camera rays on a kGrid x kGrid lattice of image positions find the shading points.
constexpr int kGrid = 96;
/// Shading points per material (evenly thinned from those the lattice finds) and estimates per point and candidate.
constexpr int kPoints = 128;
constexpr int kRepeats = 32;
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

/// A primary hit as a shading point's parts.
struct PilotPoint {
  Vec3 position;
  SurfaceView view;
};

/// The first moments of kRepeats estimates of one colour channel.
struct Moments {
  double sum = 0.0, sum_sq = 0.0;
  double mean() const { return sum / kRepeats; }
  double variance() const { return std::max(0.0, sum_sq / kRepeats - mean() * mean()) * kRepeats / (kRepeats - 1); }
};
/// Per channel (R, G, B): the images are judged by relMSE over every channel, so a channel that is dim under this
/// light (the blue of a warm interior) weighs as much as the others, which a luminance would hide.
using ChannelMoments = std::array<Moments, 3>;

/// Per scene material, the primary hits of the camera lattice that see its front.
std::vector<std::vector<PilotPoint>> pilot_points(const Scene& scene, const Camera& camera) {
  std::vector<std::vector<PilotPoint>> found(std::size_t(scene.material_count()));
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      const Ray ray = camera.generate((i + 0.5) * camera.width() / kGrid, (j + 0.5) * camera.height() / kGrid);
      Hit hit;
      if (!scene.intersect(ray, hit)) continue;
      const SurfaceView view = surface_view(hit.geometric_normal, hit.shading_normal, -ray.direction);
      if (view.wo.z > 0.0) found[std::size_t(hit.material)].push_back({hit.position, view});
    }
  return found;
}

/// At most kPoints of `all`, evenly spaced in the lattice's order.
std::vector<PilotPoint> thinned(const std::vector<PilotPoint>& all) {
  const std::size_t n = std::min<std::size_t>(kPoints, all.size());
  std::vector<PilotPoint> points;
  for (std::size_t k = 0; k < n; ++k) points.push_back(all[k * all.size() / n]);
  return points;
}

/// scores[p x C + c]: point p's relative variance under candidate c, as the images are judged (relMSE: per channel
/// the variance over the squared mean plus kRelMseFloor, the mean over every candidate since they estimate the same
/// value; averaged over the channels), times the candidate's cost per shading point.
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
/// standard errors of the per-point differences, so that the technique changes only where a gain was measured; of
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
  const std::vector<std::vector<PilotPoint>> found = pilot_points(scene_, camera);
  std::vector<LightChoice> candidates = {{true, false}, {false, false}};
  if (sun_) candidates.insert(candidates.end(), {{true, true}, {false, true}});
  for (int m = 0; m < scene_.material_count(); ++m) {
    const Material& material = scene_.material(m);
    const std::vector<PilotPoint> points = thinned(found[std::size_t(m)]);
    if (material.is_pure_delta() || points.empty()) continue;
    // moments[p x C + c]: each point's slots are its own, so the sums do not depend on the threads.
    std::vector<ChannelMoments> moments(points.size() * candidates.size());
    tbb::parallel_for(std::size_t(0), points.size(), [&](std::size_t p) {
      const SurfaceView& v = points[p].view;
      const ShadingPoint x{Scene::offset_origin(points[p].position, v.ng), v.frame, v.ng, v.wo, material};
      Sampler sampler(kPilotSeed, int(p), m);
      for (std::size_t c = 0; c < candidates.size(); ++c)
        for (int r = 0; r < kRepeats; ++r) {
          sampler.start_sample(std::uint32_t(c * kRepeats + r));
          const Vec3 e = direct_mis_with(x, sampler, candidates[c]);
          for (int ch = 0; ch < 3; ++ch) {
            const double value = std::isfinite(e[ch]) ? e[ch] : 0.0;
            Moments& mo = moments[p * candidates.size() + c][std::size_t(ch)];
            mo.sum += value;
            mo.sum_sq += value * value;
          }
        }
    });
    const LightChoice mis_choice{false, sun_ && takes_sun_samples(material)};
    const std::size_t base =
        std::size_t(std::find(candidates.begin(), candidates.end(), mis_choice) - candidates.begin());
    const std::vector<double> s = scores(moments, candidates, counts(material), options_.sun_samples);
    choices_[std::size_t(m)] = candidates[pick(s, candidates.size(), base)];
  }
}

}  // namespace envkit::render
