#include "common/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace envkit::tools {

namespace {

constexpr std::size_t kLargeWork = std::size_t(4) << 20;  // ~4M texels: a few seconds of area resampling
constexpr int kBarWidth = 30;

std::string duration_text(double seconds) {
  const long s = std::lround(std::max(seconds, 0.0));
  char buf[32];
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

}  // namespace

bool want_progress(bool forced, bool quiet, std::size_t work_texels) {
  if (quiet) return false;
  return forced || (::isatty(STDERR_FILENO) && work_texels > kLargeWork);
}

ProgressBar::ProgressBar(std::string label, bool enabled)
    : label_(std::move(label)),
      enabled_(enabled),
      tty_(::isatty(STDERR_FILENO) != 0),
      start_(Clock::now()),
      last_draw_(start_) {}

ProgressBar::~ProgressBar() {
  // Unwinding (an error) before finish(): wipe the partial bar so the error line starts clean.
  if (enabled_ && !finished_ && tty_) std::fputs("\r\033[K", stderr);
}

void ProgressBar::update(double fraction) {
  if (!enabled_ || finished_) return;
  fraction = std::clamp(fraction, 0.0, 1.0);
  if (tty_) {
    const auto now = Clock::now();
    if (now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    draw(fraction, false);
  } else {
    const int decile = static_cast<int>(fraction * 10.0);
    if (decile == last_decile_ || decile >= 10) return;  // 100% is finish()'s line
    last_decile_ = decile;
    draw(fraction, false);
  }
}

void ProgressBar::finish() {
  if (!enabled_ || finished_) return;
  finished_ = true;
  draw(1.0, true);
}

void ProgressBar::draw(double fraction, bool final_line) {
  const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
  const int filled = static_cast<int>(fraction * kBarWidth);
  std::string bar(static_cast<std::size_t>(filled), '=');
  if (filled < kBarWidth) bar += '>' + std::string(static_cast<std::size_t>(kBarWidth - filled - 1), ' ');
  std::string tail;
  if (final_line)
    tail = "done in " + duration_text(elapsed);
  else if (fraction >= 0.02 && elapsed >= 0.5)
    tail = "ETA " + duration_text(elapsed * (1.0 - fraction) / fraction);
  std::fprintf(stderr, "%s%s [%s] %3d%% %s%s", tty_ ? "\r\033[K" : "", label_.c_str(), bar.c_str(),
               static_cast<int>(fraction * 100.0), tail.c_str(), tty_ && !final_line ? "" : "\n");
  std::fflush(stderr);
}

}  // namespace envkit::tools
