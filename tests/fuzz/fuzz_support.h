#pragma once
/// @file fuzz_support.h
/// What the libFuzzer targets in tests/fuzz share: one thread, a private scratch directory (created once per
/// process, removed at exit) and a way to silence std::cout / std::cerr while a tool runs (sanitizer reports go to
/// file descriptor 2 directly, so they are never silenced).
#include <tbb/global_control.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <streambuf>
#include <string>

namespace envkit::fuzz {

/// Limits oneTBB to the calling thread for the rest of the process (every target calls it from
/// LLVMFuzzerInitialize). libFuzzer runs one small input at a time: worker threads only add their start-up and the
/// TLB shootdowns of every munmap of memory they touched on another core (a table file mapped and unmapped per
/// input), and make what an input covers depend on scheduling. A tool's --threads N then runs on one thread too
/// (oneTBB takes the smallest active limit); its parsing and validation are unchanged.
inline void run_on_one_thread() {
  static const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
}

/// Gives back the default action of the signals libFuzzer handles (every target calls it last in
/// LLVMFuzzerInitialize). Seed files written there go through AtomicOutput, whose first use installs envkit's temp
/// cleanup over each signal still at its default action; libFuzzer sets its own handlers only after Initialize and
/// leaves an installed one alone. Its SIGALRM (the -timeout watchdog, due every timeout/2 + 1 s) would then reach
/// envkit's handler, which re-raises it with the default action and ends the whole run as a finding.
inline void leave_signals_to_libfuzzer() {
  for (const int sig : {SIGALRM, SIGINT, SIGTERM, SIGUSR1, SIGUSR2, SIGXFSZ}) std::signal(sig, SIG_DFL);
}

/// The scratch directory's path, removed with the directory when the process exits. (The removal is this object's
/// destructor: an atexit handler registered while the path was being built would run after the path's destructor
/// and read freed memory.)
struct ScratchDir {
  std::filesystem::path path;
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

/// A fresh directory /tmp/envkit_fuzz_<name>_<pid> (or under $ENVKIT_FUZZ_TMP), removed when the process exits.
inline const std::filesystem::path& scratch_dir(const std::string& name = "target") {
  static const ScratchDir dir{[&] {
    const char* base = std::getenv("ENVKIT_FUZZ_TMP");
    std::filesystem::path d = std::filesystem::path(base && *base ? base : "/tmp") /
                              ("envkit_fuzz_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(d);
    std::filesystem::create_directories(d);
    return d;
  }()};
  return dir.path;
}

/// Discards everything written to std::cout and std::cerr while alive (unless ENVKIT_FUZZ_VERBOSE is set).
class SilenceStreams {
 public:
  SilenceStreams() {
    if (std::getenv("ENVKIT_FUZZ_VERBOSE")) return;
    out_ = std::cout.rdbuf(&null_);
    err_ = std::cerr.rdbuf(&null_);
  }
  ~SilenceStreams() {
    if (out_) std::cout.rdbuf(out_);
    if (err_) std::cerr.rdbuf(err_);
    std::cout.clear();
    std::cerr.clear();
  }
  SilenceStreams(const SilenceStreams&) = delete;
  SilenceStreams& operator=(const SilenceStreams&) = delete;

 private:
  struct NullBuf : std::streambuf {
    int overflow(int c) override { return c; }
    std::streamsize xsputn(const char*, std::streamsize n) override { return n; }
  } null_;
  std::streambuf* out_ = nullptr;
  std::streambuf* err_ = nullptr;
};

}  // namespace envkit::fuzz
