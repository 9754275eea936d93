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
/// Outputs that belong together (an EXR and its PNG preview, six cube faces, a map and its exported tables) are
/// committed all-or-nothing by an OutputGroup:
///
///   envkit::OutputGroup group;               // while it lives, every AtomicOutput::commit() is deferred to it
///   write_exr(a); write_png(b);              // each writer uses its own AtomicOutput as usual
///   group.commit();                          // renames every deferred temp file, or none
///
/// Temp files are named `.<name>.tmp-<pid>-<counter><ext>` in the target's directory (same file system, so
/// rename() is atomic; same extension, so extension-based format detection still picks the right writer).
///
/// Signals: the first AtomicOutput installs a handler (install_temp_cleanup_on_signal()) that removes every live temp
/// file and re-raises the signal with its default action, so the process still dies by that signal (exit status
/// 128 + N in a shell). It is run on the thread that registered the first live temp file, so that thread cannot create
/// its file after the removal. Handled: every signal whose default action ends the process and that comes from
/// outside it: SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGPIPE, SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU,
/// SIGIO, SIGPWR, SIGSTKFLT and the real-time signals SIGRTMIN..SIGRTMAX. SIGXFSZ (file size limit, `ulimit -f`)
/// instead lets the write fail with EFBIG rather than killing the process; a temp file written while SIGXFSZ arrived
/// is never committed. A handler is installed only over a signal's default action: an ignored signal stays ignored
/// (nohup) and a handler installed earlier stays in charge (Python's SIGINT raises KeyboardInterrupt; the temp file
/// is then removed by its AtomicOutput's destructor). A signal that arrives while an OutputGroup renames its files is
/// held until the group has committed (or rolled back), so a group is never left half-committed.
/// Not handled, and may leave a temp file behind (never a partial target): SIGKILL and SIGSTOP (cannot be caught), and
/// the faults and abort() (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS, SIGABRT), where the process's own state
/// is not to be trusted and sanitizers and debuggers keep their handlers.
///
/// Errors name the user's file, never a temp name: "<target>: cannot write: <strerror>" (ENOSPC, EFBIG, EACCES,
/// EIO...). A writer handed the temp path of a live AtomicOutput (a tool that stages several outputs itself) writes
/// into that file: its own AtomicOutput neither makes a second temp file nor renames, and without_temp_names()
/// turns the temp name in its messages back into the target.
#include <memory>
#include <ostream>
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
  /// Where to write. Registered for removal on the signals listed in the file comment.
  const std::string& temp_path() const { return temp_; }

  /// Flushes the temp file to disk and renames it over the target; inside an OutputGroup the rename is handed to
  /// the group instead (committed() is then true, the group owns the temp file).
  /// Throws Error("<target>: cannot write: <strerror>") if the temp file is missing, the file size limit was hit
  /// while it was written ("File too large (the file size limit, ulimit -f)"), fsync reports a failed write (a full
  /// disk), or the rename fails; the temp file is removed in that case.
  void commit();
  bool committed() const { return committed_; }

 private:
  std::string target_;      // as given
  std::string final_path_;  // target_ with a symlink resolved
  std::string temp_;
  int slot_ = -1;  // signal-cleanup registry slot, -1 when not registered
  unsigned long xfsz_at_start_ = 0;
  bool committed_ = false;
  bool passthrough_ = false;  // target_ is another AtomicOutput's temp file: write into it, do not rename
};

/// Throws Error("<target>: cannot write: <strerror(err)>"), the one wording of a failed write (EIO when err is 0).
[[noreturn]] void fail_write(const std::string& target, int err);

/// A buffered std::ostream onto an AtomicOutput's temp file that keeps the errno of the first failed write(), so
/// the error names the user's file and the cause:
///
///   envkit::AtomicOutput out(path);
///   envkit::AtomicOutputStream os(out);      // opens the temp file
///   os << ...;                               // after a failed write, further output is dropped
///   os.close();                              // flushes; throws Error("<path>: cannot write: <strerror>")
///   out.commit();
class AtomicOutputStream : public std::ostream {
 public:
  /// Opens (creates or truncates) out.temp_path(); throws Error("<target>: cannot write: <strerror>").
  explicit AtomicOutputStream(const AtomicOutput& output);
  ~AtomicOutputStream() override;
  /// Flushes and closes the file; throws Error("<target>: cannot write: <strerror>") naming the first failure.
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string target_;
};

/// All-or-nothing commit of several AtomicOutputs. While a group lives, AtomicOutput::commit() anywhere in the
/// process only fsyncs and hands its temp file to the innermost-started group (a group created while another lives
/// joins the outer one). OutputGroup::commit() then renames every file: existing targets are kept as hard-link
/// backups until all renames succeeded, and restored if one fails, so afterwards either every target holds its
/// new contents or every target is as before. Signals are held during that step (see the file comment).
/// The destructor of an uncommitted group removes every deferred temp file (nothing is committed).
class OutputGroup {
 public:
  OutputGroup();
  OutputGroup(const OutputGroup&) = delete;
  OutputGroup& operator=(const OutputGroup&) = delete;
  ~OutputGroup();
  /// Throws Error("<target>: cannot write: <reason>") naming the first target that could not be committed; then
  /// no target has changed. A joined (inner) group's commit() does nothing: the outer group commits.
  void commit();

 private:
  bool outer_ = false;
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

/// `message` with every temp file name this process's AtomicOutputs made (as a path or a bare file name) replaced by
/// its target as the caller gave it: writers' errors mention the file they were writing, which is the temp file, an
/// internal name the user never asked for. Tools pass their error messages through it.
std::string without_temp_names(const std::string& message);

/// Refuses two outputs of one run that name the same file (the later would replace the earlier):
/// Error("<b>: is the same file as the output <a>") for the first such pair, compared like check_output_path
/// (symlinks to one file, ".." paths and hard links match).
void check_distinct_outputs(const std::vector<std::string>& outputs);

/// Every output of one run, checked before any work: no two of them the same file (check_distinct_outputs), then
/// each one as check_output_path(out, inputs, force). Tools with several outputs pass all of them in one call.
void check_outputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs, bool force);

/// Installs the cleanup handler on the signals listed in the file comment (remove every live temp file, restore the
/// default action, re-raise, so the process still dies by the signal) and the SIGXFSZ handler, each only where the
/// signal has its default action when this runs (an ignored signal or another handler is left alone).
/// Idempotent; AtomicOutput calls it, tools may call it early in main(). The registry holds up to 256 concurrent
/// temp files; further ones are still removed by their destructors, just not on a signal.
void install_temp_cleanup_on_signal();

}  // namespace envkit
