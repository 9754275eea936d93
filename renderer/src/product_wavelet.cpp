#include <envkit/core/error.h>
#include <envkit/maps/octahedral.h>
#include <envkit/render/basis_hierarchy.h>
#include <envkit/render/product_wavelet.h>
#include <envkit/sampling/haar.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace envkit::render {

namespace {

/// 2 x 2 stratified points per cell for the BSDF's cell averages (the cost of the precomputation).
constexpr int kBrdfPointsPerSide = 2;
/// The bins' radius is measured on a 9 x 9 grid of each bin's points; the margin covers the points between.
constexpr double kBinRadiusMargin = 1.05;

/// Cell index of a square position, clamped to the grid (NaN -> 0).
int cell_of(double t, int n) { return t > 0.0 ? std::min(int(t * n), n - 1) : 0; }

/// The smallest rotation taking unit a to unit b, applied to v (a and b less than a right angle apart in use).
Vec3 rotate_between(const Vec3& a, const Vec3& b, const Vec3& v) {
  const Vec3 axis = a % b;  // sin(angle) x the unit axis
  const double c = a ^ b;
  return v * c + (axis % v) + axis * ((axis ^ v) / (1.0 + c));
}

/// A factor's decoded cells: Haar-transformed, compressed to `keep` coefficients, decoded, normalised to mean 1
/// and floored at kWaveletFloor (all ones when the cells hold nothing).
void encode_factor(std::vector<double>& cells, int R, int keep, float* out) {
  haar::forward(cells, R);
  haar::keep_largest(cells, R, keep);
  haar::inverse(cells, R);
  double total = 0.0;
  for (double c : cells) total += std::max(c, 0.0);
  const double mean = total / double(cells.size());
  for (std::size_t c = 0; c < cells.size(); ++c)
    out[c] = mean > 0.0 && std::isfinite(mean) ? float(std::max(cells[c] / mean, kWaveletFloor)) : 1.0f;
}

void check_options(const WaveletOptions& o) {
  static constexpr const char* kNames[] = {"resolution", "normal bins", "wo bins", "kept coefficients"};
  if (const std::optional<WaveletOptionProblem> bad = out_of_range(o))
    throw Error(std::string("wavelet ") + kNames[int(bad->member)] + " " + bad->value + ": " + bad->rule);
}

}  // namespace

Vec3 cap_from_square(Vec2 u, double h) {
  const double ax = 2.0 * u.x - 1.0, ay = 2.0 * u.y - 1.0;
  if (ax == 0.0 && ay == 0.0) return Vec3(0.0, 0.0, 1.0);
  double r, phi;
  if (std::abs(ax) > std::abs(ay)) {
    r = ax;
    phi = (kPi / 4.0) * (ay / ax);
  } else {
    r = ay;
    phi = kPi / 2.0 - (kPi / 4.0) * (ax / ay);
  }
  const double rh = std::min(r * r, 1.0) * h;                 // 1 - z: equal area, uniform in z
  const double s = std::sqrt(std::max(0.0, h * (2.0 - rh)));  // sin theta / r
  return Vec3(r * std::cos(phi) * s, r * std::sin(phi) * s, 1.0 - rh);
}

Vec2 square_from_cap(const Vec3& d, double h) {
  const double len = d.length();
  if (!(len > 0.0) || !std::isfinite(len)) return Vec2(0.5, 0.5);
  const double rho = std::sqrt(std::clamp((1.0 - d.z / len) / h, 0.0, 1.0));  // disk radius
  if (!(rho > 0.0)) return Vec2(0.5, 0.5);
  double phi = std::atan2(d.y, d.x);
  if (phi < -kPi / 4.0) phi += kTwoPi;
  double ax, ay;
  if (phi < kPi / 4.0) {
    ax = rho;
    ay = phi * (4.0 / kPi) * rho;
  } else if (phi < 3.0 * kPi / 4.0) {
    ax = (kPi / 2.0 - phi) * (4.0 / kPi) * rho;
    ay = rho;
  } else if (phi < 5.0 * kPi / 4.0) {
    ax = -rho;
    ay = -(phi - kPi) * (4.0 / kPi) * rho;
  } else {
    ax = (phi - 3.0 * kPi / 2.0) * (4.0 / kPi) * rho;
    ay = -rho;
  }
  return Vec2(std::clamp(0.5 * (ax + 1.0), 0.0, 1.0), std::clamp(0.5 * (ay + 1.0), 0.0, 1.0));
}

ProductWavelet::ProductWavelet(const SphericalDistribution& env, const std::vector<const Material*>& materials,
                               const WaveletOptions& options)
    : options_(options) {
  check_options(options_);
  const int R = options_.resolution, B = options_.normal_bins, W = options_.wo_bins;
  cells_ = std::size_t(R) * std::size_t(R);
  ones_.assign(cells_, 1.0f);

  // The bins' frames and the cap that holds the hemisphere of every normal of every bin.
  bin_frames_.resize(std::size_t(B) * std::size_t(B));
  for (std::size_t b = 0; b < bin_frames_.size(); ++b) {
    const double bx = double(b % std::size_t(B)), by = double(b / std::size_t(B));
    const Vec3 centre = OctahedralMap::direction_from_unit(Vec2((bx + 0.5) / B, (by + 0.5) / B));
    bin_frames_[b] = Frame::from_normal(centre);
    for (int fy = 0; fy <= 8; ++fy)
      for (int fx = 0; fx <= 8; ++fx)
        bin_radius_ = std::max(
            bin_radius_,
            angle_between(centre, OctahedralMap::direction_from_unit(Vec2((bx + fx / 8.0) / B, (by + fy / 8.0) / B))));
  }
  bin_radius_ = std::min(bin_radius_ * kBinRadiusMargin, kPi / 2.0);
  cap_ = 1.0 + std::sin(bin_radius_);

  // Lighting, per normal bin in its own tangent frame.
  const std::vector<EnvNode> nodes = environment_nodes(env, 8 * R, "product-wavelet");
  lighting_.resize(bin_frames_.size() * cells_);
  tbb::parallel_for(std::size_t(0), bin_frames_.size(), [&](std::size_t b) {
    const Frame& frame = bin_frames_[b];
    std::vector<double> cells(cells_, 0.0);
    for (const EnvNode& n : nodes) {
      const Vec3 local = frame.to_local(n.centre);
      if (!(local.z > 1.0 - cap_)) continue;
      const Vec2 uv = square_from_cap(local, cap_);
      cells[std::size_t(cell_of(uv.y, R)) * std::size_t(R) + std::size_t(cell_of(uv.x, R))] += n.energy;
    }
    encode_factor(cells, R, options_.kept_coefficients, lighting_.data() + b * cells_);
  });

  // BSDF x cos, per material and outgoing direction slice.
  for (const Material* m : materials)
    if (m && !m->is_pure_delta() && std::find(materials_.begin(), materials_.end(), m) == materials_.end())
      materials_.push_back(m);
  const std::size_t slices = std::size_t(W) * std::size_t(W);
  brdf_.assign(materials_.size(), std::vector<float>(slices * cells_));
  tbb::parallel_for(std::size_t(0), materials_.size() * slices, [&](std::size_t t) {
    const std::size_t mi = t / slices, slice = t % slices;
    const Material& material = *materials_[mi];
    const int wx = int(slice % std::size_t(W)), wy = int(slice / std::size_t(W));
    const Vec3 wo = cap_from_square(Vec2((wx + 0.5) / W, (wy + 0.5) / W), 1.0);
    std::vector<double> cells(cells_, 0.0);
    const int S = kBrdfPointsPerSide;
    for (int cy = 0; cy < R; ++cy)
      for (int cx = 0; cx < R; ++cx) {
        double sum = 0.0;
        for (int sy = 0; sy < S; ++sy)
          for (int sx = 0; sx < S; ++sx) {
            const Vec3 wi = cap_from_square(Vec2((cx + (sx + 0.5) / S) / R, (cy + (sy + 0.5) / S) / R), cap_);
            const Vec3 f = material.eval(wo, wi);
            const double v = (f.x + f.y + f.z) / 3.0;
            if (v > 0.0 && std::isfinite(v)) sum += v;
          }
        cells[std::size_t(cy) * std::size_t(R) + std::size_t(cx)] = sum / (S * S);
      }
    encode_factor(cells, R, options_.kept_coefficients, brdf_[mi].data() + slice * cells_);
  });
}

int ProductWavelet::bin_of(const Vec3& normal) const {
  const int B = options_.normal_bins;
  const Vec2 p = OctahedralMap::unit_from_direction(normal);
  return cell_of(p.y, B) * B + cell_of(p.x, B);
}

const float* ProductWavelet::lighting(const Vec3& normal, Frame* bin_frame) const {
  const int b = bin_of(normal);
  if (bin_frame) *bin_frame = bin_frames_[std::size_t(b)];
  return lighting_.data() + std::size_t(b) * cells_;
}

const float* ProductWavelet::brdf(const Material& material, const Vec3& wo_local) const {
  const auto it = std::find(materials_.begin(), materials_.end(), &material);
  if (it == materials_.end()) return nullptr;
  const int W = options_.wo_bins;
  const Vec2 uv = square_from_cap(wo_local, 1.0);
  const std::size_t slice = std::size_t(cell_of(uv.y, W)) * std::size_t(W) + std::size_t(cell_of(uv.x, W));
  return brdf_[std::size_t(it - materials_.begin())].data() + slice * cells_;
}

ProductWavelet::Point ProductWavelet::at(const Vec3& normal, const Vec3& wo, const Material& material) const {
  Frame frame;
  const float* light = lighting(normal, &frame);
  // The cap of the bin's frame holds the point's hemisphere when the normal lies in the bin (always, but for
  // rounding at a bin's edge); else the bin's frame turned onto the normal, whose cap holds it too.
  const Vec3 n = normal / normal.length();
  if (!(angle_between(frame.n, n) <= bin_radius_)) {
    Frame turned = Frame::from_normal(n);
    Vec3 s = (frame.n ^ n) > 0.0 ? rotate_between(frame.n, n, frame.s) : turned.s;
    s = s - n * (s ^ n);
    const double len = s.length();
    if (len > 1e-6 && std::isfinite(len)) turned = Frame(s / len, n % (s / len), n);
    frame = turned;
  }
  const float* f = brdf(material, frame.to_local(wo));
  if (!f) f = ones_.data();
  std::vector<float> product(cells_);
  for (std::size_t c = 0; c < cells_; ++c) product[c] = light[c] * f[c];
  return Point(frame, product, options_.resolution, cap_);
}

std::size_t ProductWavelet::bytes() const {
  std::size_t b = (lighting_.size() + ones_.size()) * sizeof(float) + bin_frames_.size() * sizeof(Frame);
  for (const auto& m : brdf_) b += m.size() * sizeof(float);
  return b;
}

ProductWavelet::Point::Point(const Frame& frame, const std::vector<float>& product, int R, double cap)
    : frame_(frame), cap_(cap), product_(product.data(), R, R) {}

DirectionSample ProductWavelet::Point::sample(Vec2 u) const {
  const DistributionSample s = product_.sample(u);
  DirectionSample d;
  d.direction = frame_.to_world(cap_from_square(s.uv, cap_));
  d.pdf = s.pdf / (kTwoPi * cap_);
  d.x = s.x;
  d.y = s.y;
  return d;
}

double ProductWavelet::Point::pdf(const Vec3& direction) const {
  const Vec3 local = frame_.to_local(direction);
  const double len = local.length();
  if (!(len > 0.0) || !(local.z > (1.0 - cap_) * len)) return 0.0;
  return product_.pdf(square_from_cap(local, cap_)) / (kTwoPi * cap_);
}

std::optional<WaveletOptionProblem> out_of_range(const WaveletOptions& o) {
  using M = WaveletOptionProblem::Member;
  if (!haar::valid_size(o.resolution) || o.resolution > 256)
    return WaveletOptionProblem{M::Resolution, std::to_string(o.resolution), "must be a power of two in 2..256"};
  if (o.normal_bins < 1 || o.normal_bins > 64)
    return WaveletOptionProblem{M::NormalBins, std::to_string(o.normal_bins), "must be in 1..64"};
  if (o.wo_bins < 1 || o.wo_bins > 64)
    return WaveletOptionProblem{M::WoBins, std::to_string(o.wo_bins), "must be in 1..64"};
  if (o.kept_coefficients < 0)
    return WaveletOptionProblem{M::KeptCoefficients, std::to_string(o.kept_coefficients), "must be >= 0 (0 = all)"};
  return std::nullopt;
}

}  // namespace envkit::render
