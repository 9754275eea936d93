// envsample: draws directions from baked tables and writes them as CSV, or as a picture of where they land
// on the lat-long image (the seed's "Resulting Sample Distribution" figure).
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <envkit/sampling/sampler.h>
#include <envkit/tables/env_tables.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "common/cli.h"

namespace {

namespace tools = envkit::tools;
namespace fs = std::filesystem;

const char* kFooter = R"(Output by extension:
  .csv       one line per sample: u0,u1,x,y,z,pdf,texel_x,texel_y (direction in the tables' world frame,
             +Y up; pdf per steradian)
  .png/.jpg  the importance map (log-scaled grey) with the samples as red dots, over a lat-long image
  .exr       float lat-long images: R = sample density (count / (N x texel solid angle)), G = the tables'
             pdf; both per steradian, so R converges to G as N grows
--sequence sobol draws Owen-scrambled Sobol points (stratified: hierarchical keeps the stratification,
alias destroys it); random draws 53-bit uniform doubles (std::mt19937_64). Same --seed, same samples.

Examples:
  envsample sky.envtbl -n 4096 --method hierarchical -o samples.png
  envsample sky.envtbl -n 100000 --method alias --sequence random -o samples.csv
  envsample sky.envtbl -n 1000000 --method cdf -o density.exr --width 1024

Exit status: 0 success; 1 error (one line on stderr, no output file written); 2 usage error.)";

struct Options {
  std::string tables, out, sequence = "sobol";
  envkit::SamplingMethod method = envkit::SamplingMethod::Hierarchical;
  std::size_t n = 4096;
  std::uint32_t seed = 0;
  int width = 0;
  bool compensated = false, force = false, quiet = false;
};

std::string lower_extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

/// u for sample i, deterministic for a seed.
class Sequence {
 public:
  Sequence(bool sobol, std::uint32_t seed) : sobol_(sobol), rng_(seed), sampler_(seed, 0, 0) {}
  envkit::Vec2 next(std::uint32_t i) {
    if (!sobol_) return envkit::Vec2(uniform_(rng_), uniform_(rng_));
    sampler_.start_sample(i);
    return sampler_.next_2d();
  }

 private:
  bool sobol_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  envkit::OwenSobolSampler sampler_;
};

void write_csv(const std::string& path, const envkit::SphericalDistribution& d, Sequence& seq, std::size_t n) {
  envkit::AtomicOutput out(path);
  {
    envkit::AtomicOutputStream f(out);
    f << "u0,u1,x,y,z,pdf,texel_x,texel_y\n" << std::setprecision(17);
    for (std::size_t i = 0; i < n; ++i) {
      const envkit::Vec2 u = seq.next(std::uint32_t(i));
      const envkit::DirectionSample s = d.sample(u);
      f << u.x << ',' << u.y << ',' << s.direction.x << ',' << s.direction.y << ',' << s.direction.z << ',' << s.pdf
        << ',' << s.x << ',' << s.y << '\n';
    }
    f.close();
  }
  out.commit();
}

/// The lat-long picture: density and pdf (EXR) or importance with dots (8-bit).
void write_picture(const std::string& path, const envkit::EnvTables& t, const envkit::SphericalDistribution& d,
                   Sequence& seq, std::size_t n, int width) {
  const int W = width > 0 ? width : std::clamp(2 * t.height(), 256, 2048);
  const int H = std::max(1, W / 2);
  const envkit::LatLongMap map(W, H);
  const bool exr = lower_extension(path) == ".exr";
  envkit::Image image(W, H, 3);

  std::vector<double> counts(std::size_t(W) * H, 0.0);
  std::vector<std::pair<int, int>> dots;
  // Blocks of u through the batched sample() (the same samples as one call each; the table misses overlap).
  constexpr std::size_t kBlock = 1024;
  std::vector<envkit::Vec2> u(kBlock);
  std::vector<envkit::DirectionSample> samples(kBlock);
  for (std::size_t b = 0; b < n; b += kBlock) {
    const std::size_t m = std::min(kBlock, n - b);
    for (std::size_t i = 0; i < m; ++i) u[i] = seq.next(std::uint32_t(b + i));
    d.sample(std::span<const envkit::Vec2>(u.data(), m), std::span<envkit::DirectionSample>(samples.data(), m));
    for (std::size_t i = 0; i < m; ++i) {
      const envkit::Vec2 p = map.to_image(samples[i].direction);
      const int x = std::clamp(int(p.x), 0, W - 1), y = std::clamp(int(p.y), 0, H - 1);
      counts[std::size_t(y) * W + x] += 1.0;
      if (!exr && dots.size() < 200000) dots.emplace_back(x, y);
    }
  }
  // Background: log(1 + pdf / mean pdf) scaled to its maximum, so a sun does not blacken the sky.
  std::vector<double> pdf(counts.size());
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      envkit::Vec3 dir;
      map.to_direction(envkit::Vec2(x + 0.5, y + 0.5), dir);
      pdf[std::size_t(y) * W + x] = d.pdf(dir);
    }
  const double mean_pdf = 1.0 / envkit::kFourPi;
  double max_log = 0.0;
  for (double p : pdf) max_log = std::max(max_log, std::log1p(p / mean_pdf));
  for (int y = 0; y < H; ++y) {
    const double omega = map.solid_angle(0.0, y, 1.0, y + 1.0);
    for (int x = 0; x < W; ++x) {
      const std::size_t i = std::size_t(y) * W + x;
      float* px = image.at(x, y);
      if (exr) {
        px[0] = static_cast<float>(counts[i] / (double(n) * omega));
        px[1] = static_cast<float>(pdf[i]);
        px[2] = 0.0f;
      } else {
        const float grey = max_log > 0.0 ? static_cast<float>(0.35 * std::log1p(pdf[i] / mean_pdf) / max_log) : 0.0f;
        px[0] = px[1] = px[2] = grey;
      }
    }
  }
  const int dot = W >= 1024 ? 2 : 1;
  for (const auto& [x, y] : dots)
    for (int dy = 0; dy < dot; ++dy)
      for (int dx = 0; dx < dot; ++dx) {
        float* px = image.at(std::min(x + dx, W - 1), std::min(y + dy, H - 1));
        px[0] = 1.0f;
        px[1] = px[2] = 0.0f;
      }
  image.channel_names = {"R", "G", "B"};
  envkit::WriteOptions wo;
  wo.metadata["envkit:description"] =
      exr ? "R: sample density per steradian, G: pdf per steradian" : "importance (log grey) and samples (red)";
  envkit::write_image(path, image, wo);
}

int run(const Options& o) {
  const std::string ext = lower_extension(o.out);
  if (ext != ".csv" && ext != ".png" && ext != ".jpg" && ext != ".jpeg" && ext != ".exr")
    throw CLI::ValidationError("--output", "use a .csv, .png, .jpg or .exr file");
  envkit::check_output_path(o.out, {o.tables}, o.force);
  envkit::install_temp_cleanup_on_signal();
  const envkit::EnvTables t = envkit::EnvTables::load(o.tables);
  const envkit::SamplingMethod method = o.method;
  const envkit::SphericalDistribution* d = t.distribution(method, o.compensated);
  if (!d)
    throw envkit::Error(o.tables + ": has no " + envkit::table_name(method, o.compensated) +
                        " table (re-bake with envbake --tables ...)");
  Sequence seq(o.sequence == "sobol", o.seed);
  if (ext == ".csv")
    write_csv(o.out, *d, seq, o.n);
  else
    write_picture(o.out, t, *d, seq, o.n, o.width);
  if (!o.quiet)
    tools::info("wrote " + std::to_string(o.n) + " " + envkit::method_name(method) + " samples (" + o.sequence +
                ") to " + o.out);
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Draws directions from baked tables and writes them as CSV or a picture of their distribution.",
               "envsample");
  Options o;
  app.add_option("TABLES", o.tables, "table file from envbake")->required()->type_name("FILE");
  app.add_option("-o,--output", o.out, "output: .csv, .png/.jpg or .exr")->required()->type_name("OUT");
  app.add_option("-n,--samples", o.n, "number of samples")
      ->transform(tools::integer_in(1, 1LL << 32))
      ->capture_default_str();
  tools::add_parsed_option(app, "--method", o.method, envkit::parse_method, "cdf, alias or hierarchical")
      ->default_str("hierarchical");
  app.add_option("--sequence", o.sequence, "random or sobol")
      ->check(CLI::IsMember({"random", "sobol"}))
      ->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the sequence")
      ->transform(tools::integer_in(0, 4294967295LL))
      ->capture_default_str();
  app.add_option("--width", o.width, "picture width (height = width / 2)")->transform(tools::integer_in(2, 16384));
  app.add_flag("--compensated", o.compensated, "sample the MIS-compensated table");
  app.add_flag("-f,--force", o.force, "allow OUT to overwrite TABLES");
  app.add_flag("-q,--quiet", o.quiet, "print only errors");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return run(o); });
}
