#pragma once
/// @file atomic_file.h
/// Atomic output files: write to a temporary file next to the target, then rename() it over the target.
/// A reader never sees a half-written file, and a failed or interrupted write leaves the target untouched
/// (an existing target keeps its old contents; a new target does not appear).
///
///   envkit::AtomicOutput out(path);          // checks the directory, picks the temp name
///   write_whatever(out.temp_path());         // may throw: ~AtomicOutput removes the temp file
///   out.commit();                            // rename(temp, path)
///
/// Temp files are named `.<name>.tmp-<pid>-<counter><ext>` in the target's directory (same file system, so
/// rename() is atomic; same extension, so extension-based format detection still picks the right writer).
#include <string>
#include <vector>

namespace envkit {

class AtomicOutput {
 public:
  /// Prepares a temp path for `target` (nothing is created yet). If `target` is an existing symlink, the
  /// file it points to is replaced, not the link. Throws Error("<target>: directory '<dir>' does not exist")
  /// or Error("<target>: cannot write: <reason>") when the directory is missing or not writable.
  explicit AtomicOutput(std::string target);
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  /// Removes the temp file if commit() did not succeed.
  ~AtomicOutput();

  /// The path as given by the caller (use it in messages).
  const std::string& target() const { return target_; }
  /// Where to write. Registered for removal on SIGINT/SIGTERM (see install_temp_cleanup_on_signal()).
  const std::string& temp_path() const { return temp_; }

  /// Flushes the temp file to disk and renames it over the target.
  /// Throws Error("<target>: cannot write: <reason>") if the temp file is missing or the rename fails;
  /// the temp file is removed in that case.
  void commit();
  bool committed() const { return committed_; }

 private:
  std::string target_;     // as given
  std::string final_path_; // target_ with a symlink resolved
  std::string temp_;
  int slot_ = -1;          // signal-cleanup registry slot, -1 when not registered
  bool committed_ = false;
};

/// Validates an output path before any work is done:
///  - Error("<out>: output path is the same as input <in>; pass --force to overwrite it") when `out` names
///    the same file as one of `inputs` (compared after std::filesystem::weakly_canonical, so "./a.exr" and
///    "dir/../a.exr" match, and by device/inode for existing files, so hard links match too); skipped when
///    `force` is true;
///  - Error("<out>: is a directory");
///  - Error("<out>: directory '<dir>' does not exist") / Error("<out>: cannot write: <strerror>") when the
///    parent directory is missing or not writable (access(W_OK); note that root passes this check).
void check_output_path(const std::string& out, const std::vector<std::string>& inputs, bool force);

/// Installs SIGINT/SIGTERM/SIGHUP handlers that unlink every live AtomicOutput temp file, then restore the
/// previous handler and re-raise the signal (so the process still dies with the signal, or the previous
/// handler runs). Idempotent; call it once early in main(). The registry holds up to 64 concurrent temp
/// files; further ones are still removed by their destructors, just not on a signal.
void install_temp_cleanup_on_signal();

}  // namespace envkit
