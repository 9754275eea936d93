#include <envkit/render/render.h>
#include <pmmintrin.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>
#include <time.h>
#include <xmmintrin.h>

#include <atomic>
#include <chrono>
#include <mutex>

namespace envkit::render {

namespace {

/// Sets flush-to-zero and denormals-are-zero for the current thread (Embree's recommendation) and restores the
/// previous mode on exit, so TBB workers shared with other code are left as they were.
class DenormalGuard {
 public:
  DenormalGuard() : saved_(_mm_getcsr()) {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  }
  ~DenormalGuard() { _mm_setcsr(saved_); }

 private:
  unsigned saved_;
};

/// The calling thread's CPU time in seconds: a pixel's cost without the time the thread spent preempted (on a shared
/// machine a wall clock would charge a whole time slice to whichever pixel was running).
double thread_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

void render_pass(const Camera& camera, const Integrator& integrator, Film& film, std::uint32_t seed,
                 std::uint32_t first_index, int count, int tile, const std::function<void()>& tile_done) {
  const Crop& crop = film.crop();
  const int tiles_x = (crop.width() + tile - 1) / tile, tiles_y = (crop.height() + tile - 1) / tile;
  const bool timed = film.timed();
  tbb::parallel_for(tbb::blocked_range2d<int>(0, tiles_y, 0, tiles_x), [&](const tbb::blocked_range2d<int>& r) {
    DenormalGuard guard;
    for (int ty = r.rows().begin(); ty < r.rows().end(); ++ty)
      for (int tx = r.cols().begin(); tx < r.cols().end(); ++tx) {
        const int x0 = tx * tile, y0 = ty * tile;
        const int x1 = std::min(x0 + tile, crop.width()), y1 = std::min(y0 + tile, crop.height());
        for (int y = y0; y < y1; ++y)
          for (int x = x0; x < x1; ++x) {
            const int px = crop.x0 + x, py = crop.y0 + y;
            const double start = timed ? thread_seconds() : 0.0;
            Sampler sampler(seed, px, py);
            for (int i = 0; i < count; ++i) {
              sampler.start_sample(first_index + std::uint32_t(i));
              const Vec2 jitter = sampler.next_2d();
              const Ray ray = camera.generate(px + jitter.x, py + jitter.y);
              film.add(x, y, integrator.radiance(ray, sampler));
            }
            if (timed) film.add_seconds(x, y, thread_seconds() - start);
          }
        if (tile_done) tile_done();
      }
  });
}

}  // namespace

Film render_image(const Camera& camera, const Integrator& integrator, const RenderOptions& options,
                  RenderStats* stats) {
  Crop crop = options.crop;
  if (crop.x0 == 0 && crop.y0 == 0 && crop.x1 == 0 && crop.y1 == 0) crop = Crop{0, 0, camera.width(), camera.height()};
  Film film(camera.width(), camera.height(), crop);
  if (options.pixel_seconds) film.set_timed();
  const int tile = std::max(1, options.tile_size);
  const std::size_t tiles =
      std::size_t((crop.width() + tile - 1) / tile) * std::size_t((crop.height() + tile - 1) / tile);
  std::mutex progress_mutex;
  std::atomic<std::size_t> done{0};
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  int spp = 0;

  if (options.time_seconds > 0.0) {
    const int pass = std::max(1, options.pass_spp);
    do {
      render_pass(camera, integrator, film, options.seed, std::uint32_t(spp), pass, tile, nullptr);
      spp += pass;
      if (options.progress) {
        std::lock_guard lock(progress_mutex);
        options.progress(std::min(1.0, elapsed() / options.time_seconds));
      }
    } while (elapsed() < options.time_seconds);
  } else {
    spp = std::max(1, options.spp);
    auto tile_done = [&] {
      const std::size_t n = ++done;
      if (options.progress) {
        std::lock_guard lock(progress_mutex);
        options.progress(double(n) / double(tiles));
      }
    };
    render_pass(camera, integrator, film, options.seed, 0, spp, tile, tile_done);
  }
  if (stats) {
    stats->seconds = elapsed();
    stats->samples = film.total_samples();
    stats->spp = spp;
  }
  return film;
}

}  // namespace envkit::render
