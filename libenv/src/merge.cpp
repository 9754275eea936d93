#include <envkit/error.h>
#include <envkit/merge.h>
#include <envkit/solid_angle_table.h>
#include <envkit/texel_directions.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace envkit {

namespace {

// R, G, B premultiplied by mask x exposure, then the mask itself as a fourth
// colour channel (alpha -1): one resample carries the masked mean colour and
// the mask's mean, and the resampler adds coverage alpha where the capture does
// not see the whole texel.
Image masked_capture(const Capture &c) {
  const Image &img = c.map.image;
  std::vector<int> colour;
  for (int ch = 0; ch < img.channels; ++ch)
    if (ch != img.alpha_channel)
      colour.push_back(ch);
  if (colour.size() == 2 || colour.empty())
    throw Error(c.name +
                ": a capture needs 1 or at least 3 colour channels, not " +
                std::to_string(colour.size()));
  if (colour.size() == 1)
    colour = {colour[0], colour[0], colour[0]};
  if (c.mask && (c.mask->width != img.width || c.mask->height != img.height))
    throw Error(c.name + ": mask is " + std::to_string(c.mask->width) + "x" +
                std::to_string(c.mask->height) + " but the capture is " +
                std::to_string(img.width) + "x" + std::to_string(img.height));
  Image out(img.width, img.height, 4);
  out.channel_names = {"R", "G", "B", "M"};
  out.alpha_channel = -1; // M is resampled like colour; the resampler's own
                          // alpha is the coverage
  tbb::parallel_for(0, img.height, [&](int j) {
    for (int i = 0; i < img.width; ++i) {
      double m =
          c.mask ? std::clamp(double(c.mask->at(i, j, 0)), 0.0, 1.0) : 1.0;
      if (img.alpha_channel >= 0)
        m *= std::clamp(double(img.at(i, j, img.alpha_channel)), 0.0, 1.0);
      for (int k = 0; k < 3; ++k)
        out.at(i, j, k) = float(img.at(i, j, colour[k]) * c.exposure * m);
      out.at(i, j, 3) = float(m);
    }
  });
  return out;
}

} // namespace

Image merge_captures(const std::vector<Capture> &captures,
                     const Parameterization &dst, const Mat3 &dst_to_world,
                     MergeReport *report, const ResampleOptions &options) {
  if (captures.empty())
    throw Error("nothing to merge: no captures");
  const int W = dst.width(), H = dst.height();
  const std::size_t texels = std::size_t(W) * H;
  const TexelDirections dirs(dst);
  const SolidAngleTable omega(dst);
  std::vector<double> num(texels * 3, 0.0), den(texels, 0.0), best(texels, 0.0);
  std::vector<std::vector<float>> weights(captures.size()),
      seen_by(captures.size());
  ResampleOptions opt = options;
  opt.filter = Filter::Area;
  for (std::size_t k = 0; k < captures.size(); ++k) {
    const Capture &c = captures[k];
    const Image src = masked_capture(c);
    const Image r =
        resample({src, *c.map.param, c.map.to_world()}, dst, dst_to_world, opt);
    const Mat3 dst_to_src = compose(transposed(c.map.to_world()), dst_to_world);
    weights[k].assign(texels, 0.0f);
    seen_by[k].assign(texels, 0.0f);
    const double mean_per_pixel = SolidAngleTable(*c.map.param).total() /
                                  (double(src.width) * src.height);
    tbb::parallel_for(0, H, [&](int j) {
      for (int i = 0; i < W; ++i) {
        const std::size_t t = std::size_t(j) * W + i;
        const double coverage =
            r.channels > 4 ? std::clamp(double(r.at(i, j, 4)), 0.0, 1.0) : 1.0;
        const double mask = std::clamp(double(r.at(i, j, 3)), 0.0, 1.0);
        const double seen = coverage * mask;
        if (!(seen > 0.0))
          continue;
        Vec3 d;
        if (!dirs.centre(i, j, d))
          continue;
        // Sampling density where the capture sees the texel centre; a centre
        // just outside a capture that sees part of the texel takes the
        // capture's mean density instead.
        const Vec2 p = c.map.param->to_image(apply(dst_to_src, d));
        const bool inside =
            p.x >= 0 && p.y >= 0 && p.x <= src.width && p.y <= src.height;
        double per_pixel = inside ? c.map.param->solid_angle_density(p) : 0.0;
        if (!(per_pixel > 0.0))
          per_pixel = mean_per_pixel;
        const double w = seen / per_pixel;
        // Colour over mask: the capture's radiance averaged over the part of
        // the texel its mask keeps.
        for (int ch = 0; ch < 3; ++ch)
          num[t * 3 + ch] += w * r.at(i, j, ch) / mask;
        den[t] += w;
        best[t] = std::max(best[t], seen);
        weights[k][t] = float(w);
        seen_by[k][t] = float(seen);
      }
    });
  }
  Image out(W, H, 4);
  out.channel_names = {"R", "G", "B", "A"};
  out.alpha_channel = 3;
  out.metadata = captures[0].map.image.metadata;
  double uncovered = 0.0;
  std::vector<double> covered(captures.size(), 0.0),
      share(captures.size(), 0.0);
  double total_weight = 0.0;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const std::size_t t = std::size_t(j) * W + i;
      const double o = omega(i, j);
      uncovered += o * (1.0 - best[t]);
      for (std::size_t k = 0; k < captures.size(); ++k)
        covered[k] += o * seen_by[k][t];
      if (den[t] > 0.0) {
        for (int ch = 0; ch < 3; ++ch)
          out.at(i, j, ch) = float(num[t * 3 + ch] / den[t]);
        out.at(i, j, 3) = float(best[t]);
        for (std::size_t k = 0; k < captures.size(); ++k) {
          const double w = weights[k][t] / den[t] * o;
          share[k] += w;
          total_weight += w;
        }
      }
    }
  if (report) {
    report->uncovered_solid_angle = uncovered;
    for (std::size_t k = 0; k < captures.size(); ++k)
      share[k] = total_weight > 0.0 ? share[k] / total_weight : 0.0;
    report->weight_share = share;
    report->covered_solid_angle = covered;
  }
  return out;
}

} // namespace envkit
