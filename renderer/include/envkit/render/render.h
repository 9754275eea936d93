#pragma once
/// @file render.h
/// The render loop: oneTBB over 16x16 tiles, Owen-scrambled Sobol samples seeded per pixel (so results do not
/// depend on the thread count or the tile order, and a crop reproduces the full render's pixels), FTZ/DAZ set
/// on every worker while it traces. Either a fixed number of samples per pixel or a time budget (passes of
/// `pass_spp` samples until the time is spent; at least one pass).
#include <envkit/render/camera.h>
#include <envkit/render/film.h>
#include <envkit/render/integrator.h>

#include <cstdint>
#include <functional>

namespace envkit::render {

struct RenderOptions {
  int spp = 16;               ///< samples per pixel (ignored when time_seconds > 0)
  double time_seconds = 0.0;  ///< > 0: render passes until this much time has passed
  int pass_spp = 1;           ///< samples per pixel per pass in time mode
  std::uint32_t seed = 0;
  Crop crop{};  ///< empty (all zero) = the whole image
  int tile_size = 16;
  /// Time each pixel's samples (the rendering thread's CPU time around them, summed over the passes) into the film's
  /// seconds (Film::timed): what a region of the image cost. The samples and their values are the same either way.
  bool pixel_seconds = false;
  /// Called with the fraction done (from any thread, serialised).
  std::function<void(double)> progress;
};

struct RenderStats {
  double seconds = 0;
  std::uint64_t samples = 0;
  int spp = 0;  ///< samples per pixel actually taken
};

Film render_image(const Camera& camera, const Integrator& integrator, const RenderOptions& options,
                  RenderStats* stats = nullptr);

}  // namespace envkit::render
