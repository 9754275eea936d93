#pragma once
/// @file progress.h
/// A one-line progress bar with percentage and ETA on stderr, fed by libenv's ProgressFn.
#include <envkit/resample/resample.h>

#include <chrono>
#include <cstddef>
#include <string>

namespace envkit::tools {

/// Whether to draw progress: never with --quiet; always with --progress; otherwise only when stderr is a
/// terminal and the work is large (more than ~4M output texels), so small jobs and logs stay clean.
bool want_progress(bool forced, bool quiet, std::size_t work_texels);

class ProgressBar {
 public:
  /// A disabled bar ignores every call, so callers need no conditionals.
  ProgressBar(std::string label, bool enabled);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  /// fraction in [0, 1]. Redraws at most ~10 times a second on a terminal; on a pipe or file (--progress
  /// into a log) prints one line per 10%.
  void update(double fraction);
  /// Draws 100% with the elapsed time and ends the line (idempotent). Without it (an error unwinding), the
  /// destructor erases the partial bar.
  void finish();
  /// Callback for ResampleOptions::progress; the bar must outlive the resampling.
  ProgressFn callback() {
    return [this](double f) { update(f); };
  }

 private:
  using Clock = std::chrono::steady_clock;
  void draw(double fraction, bool final_line);

  std::string label_;
  bool enabled_;
  bool tty_;
  bool finished_ = false;
  Clock::time_point start_, last_draw_;
  int last_decile_ = 0;  // 0% is not worth a line
};

}  // namespace envkit::tools
