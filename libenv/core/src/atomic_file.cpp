#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/core/excerpt.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <utility>

namespace envkit {
namespace fs = std::filesystem;

namespace {

// What the process is doing, for the handler: a group commit must not be cut in half, so a signal arriving during
// one is held (g_pending) and re-raised when the renames are done.
enum Phase : int { kIdle = 0, kCommitting = 1, kDying = 2 };
std::atomic<int> g_phase{kIdle};

// ---- registry of live temp files, read by the signal handler -------------------------------------------
// Fixed storage and lock-free atomics only: the handler may run at any point, on any thread.
constexpr int kSlots = 256;
constexpr std::size_t kMaxPath = 4096;
enum SlotState : int { kFree = 0, kBusy = 1, kLive = 2 };

struct Slot {
  std::atomic<int> state{kFree};
  std::atomic<pid_t> owner{0};  // the thread that registered the temp file and goes on to create it; 0: unknown
  char path[kMaxPath] = {};
};
// Constant-initialised (zeros in .bss): no start-up code touches its megabyte, only the slots in use are paged in.
constinit std::array<Slot, kSlots> g_slots{};
static_assert(std::atomic<int>::is_always_lock_free, "signal handler needs lock-free atomics");

// Every signal whose default action ends the process and that comes from outside it (kill, the terminal, a timer,
// a closed pipe, a CPU limit), plus the real-time signals. Left out: SIGKILL and SIGSTOP (cannot be caught), the
// faults and abort() (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS, SIGABRT: the process's own state is then not
// to be trusted, and sanitizers and debuggers own them), and SIGXFSZ (handled apart: the write fails instead).
constexpr std::array<int, 14> kFixedSignals = {SIGHUP,  SIGINT,    SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGPIPE,
                                               SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU, SIGIO,   SIGPWR,  SIGSTKFLT};

/// The signals cleaned up on (kFixedSignals and SIGRTMIN..SIGRTMAX), in a set.
const sigset_t& cleanup_signals() {
  static const sigset_t set = [] {
    sigset_t s;
    sigemptyset(&s);
    for (int sig : kFixedSignals) sigaddset(&s, sig);
    for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) sigaddset(&s, sig);
    return s;
  }();
  return set;
}

/// False when this thread blocks one of the cleanup signals (a worker a library started with every signal blocked):
/// a signal handed on to it would never be taken.
bool takes_signals() {
  sigset_t mask;
  if (::pthread_sigmask(SIG_BLOCK, nullptr, &mask) != 0) return false;
  for (int sig = 1; sig < NSIG; ++sig)
    if (sigismember(&cleanup_signals(), sig) == 1 && sigismember(&mask, sig) == 1) return false;
  return true;
}

int register_temp(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  // A signal handler is removing the live temp files and ending the process: a file registered now would be left.
  while (g_phase.load() == kDying) ::usleep(1000);
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (g_slots[i].state.compare_exchange_strong(expected, kBusy)) {
      g_slots[i].owner.store(takes_signals() ? ::gettid() : 0);
      std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
      g_slots[i].state.store(kLive);
      return i;
    }
  }
  return -1;  // full: the destructor still cleans up, only signal cleanup is lost
}

void unregister_temp(int slot) {
  if (slot < 0) return;
  g_slots[slot].state.store(kBusy);  // the handler skips busy slots
  g_slots[slot].state.store(kFree);
}

// The action each cleanup signal had before (by signal number), restored before the signal is raised again.
std::array<struct sigaction, NSIG> g_previous{};

std::atomic<int> g_pending{0};
// SIGXFSZ deliveries so far: a temp file written while one arrived is truncated and must not be committed.
std::atomic<unsigned long> g_xfsz{0};
static_assert(std::atomic<unsigned long>::is_always_lock_free, "signal handler needs lock-free atomics");

void remove_live_temps_and_reraise(int sig) {
  for (auto& slot : g_slots)
    if (slot.state.load() == kLive) ::unlink(slot.path);  // async-signal-safe
  // Restore the default action (the handler is only installed over it) and re-raise at once, unblocked, so that the
  // process ends here by that signal: were it delivered only when this handler returns, the other threads would run
  // on meanwhile and could create a temp file after the loop above removed the live ones.
  ::sigaction(sig, &g_previous[std::size_t(sig)], nullptr);
  sigset_t just_this;
  sigemptyset(&just_this);
  sigaddset(&just_this, sig);
  ::pthread_sigmask(SIG_UNBLOCK, &just_this, nullptr);
  ::raise(sig);
}

/// The thread that must handle the signal: the one that registered the first live temp file, if that is not this
/// one. A library creates the temp file some time after it was registered; were the files removed from another
/// thread, the owner could create its file in the microseconds before the process ends. Handled on the owner, the
/// signal interrupts it between system calls: every file it created is registered and removed. Deterministic (the
/// first slot in order), so two threads never hand the signal back and forth; 0 when this thread is the one.
pid_t thread_to_handle(pid_t self) {
  for (const auto& slot : g_slots) {
    const int state = slot.state.load();
    if (state == kFree) continue;
    const pid_t owner = slot.owner.load();
    return owner == self ? 0 : owner;  // 0 (an owner that blocks the signals): handled here
  }
  return 0;
}

extern "C" void cleanup_on_signal(int sig) {
  const int saved_errno = errno;
  const pid_t self = ::gettid();
  if (const pid_t owner = thread_to_handle(self);
      owner != 0 && g_phase.load() != kDying && ::syscall(SYS_tgkill, ::getpid(), owner, sig) == 0) {
    errno = saved_errno;
    return;  // pending on the owner until it unblocks the signal, if it has it blocked right now
  }
  for (;;) {
    int expected = kIdle;
    if (g_phase.compare_exchange_strong(expected, kDying)) {
      // Handled here: a copy this handler may have left for a commit that ended meanwhile must not be raised again
      // by a later commit, should the process survive the signal.
      int left = sig;
      g_pending.compare_exchange_strong(left, 0);
      remove_live_temps_and_reraise(sig);
      // The previous handler may return (a tool that handles the signal itself): the process lives on.
      g_phase.store(kIdle);
      break;
    }
    if (expected == kDying) break;  // another thread is already cleaning up and re-raising
    // A group commit is running: its thread re-raises the signal when the renames are done. Had it finished them
    // between the two loads, it may have looked for the signal before it was left: then take it here again.
    g_pending.store(sig);
    if (g_phase.load() == kCommitting) break;
  }
  errno = saved_errno;
}

extern "C" void note_file_size_limit(int) { g_xfsz.fetch_add(1); }  // write() then fails with EFBIG

/// Installs `action` for `sig` only where the signal still has its default action: an ignored signal (nohup's
/// SIGHUP, Python's SIGPIPE) stays ignored, and a handler someone else installed (Python's SIGINT, which raises
/// KeyboardInterrupt; a profiler's SIGPROF; a sanitizer's) stays theirs.
void install_over_default(int sig, const struct sigaction& action) {
  struct sigaction& previous = g_previous[std::size_t(sig)];
  if (::sigaction(sig, nullptr, &previous) != 0) return;
  if ((previous.sa_flags & SA_SIGINFO) || previous.sa_handler != SIG_DFL) return;
  ::sigaction(sig, &action, nullptr);
}

/// Holds signals for the duration of a group commit (see g_phase).
class HeldSignals {
 public:
  HeldSignals() {
    for (;;) {
      int expected = kIdle;
      if (g_phase.compare_exchange_weak(expected, kCommitting)) return;
      ::usleep(1000);  // a handler is cleaning up: the process is about to end
    }
  }
  ~HeldSignals() {
    // Idle first, then look for a held signal: a handler that ran in between either left it before this looks
    // (raised here) or saw the phase idle and handled it itself.
    g_phase.store(kIdle);
    const int sig = g_pending.exchange(0);
    if (sig != 0) ::raise(sig);
  }
};

std::atomic<unsigned long> g_counter{0};

std::string errno_text(int err) { return std::strerror(err); }

// ---- the temp names this process made, for messages and for writers handed a temp path -----------------------
struct TempName {
  std::string temp, target;
  bool live = true;
};
std::mutex g_names_mutex;
std::vector<TempName> g_names;  // oldest first; finished ones are dropped beyond kRememberedNames
constexpr std::size_t kRememberedNames = 1024;

void remember_temp(const std::string& temp, const std::string& target) {
  std::lock_guard<std::mutex> lock(g_names_mutex);
  if (g_names.size() >= kRememberedNames)
    if (auto it = std::find_if(g_names.begin(), g_names.end(), [](const TempName& n) { return !n.live; });
        it != g_names.end())
      g_names.erase(it);
  g_names.push_back({temp, target, true});
}

/// Marks `temp` as finished (committed or removed); its name is still translated in messages.
void retire_temp(const std::string& temp) {
  std::lock_guard<std::mutex> lock(g_names_mutex);
  for (TempName& n : g_names)
    if (n.temp == temp) n.live = false;
}

bool is_live_temp(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_names_mutex);
  return std::any_of(g_names.begin(), g_names.end(), [&](const TempName& n) { return n.live && n.temp == path; });
}

void replace_all(std::string& text, const std::string& from, const std::string& to) {
  if (from.empty()) return;
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
}

/// The file that will really be replaced: an existing symlink is followed so the link survives.
fs::path resolve_target(const std::string& target) {
  std::error_code ec;
  fs::path p(target);
  if (fs::is_symlink(fs::symlink_status(p, ec))) {
    fs::path resolved = fs::weakly_canonical(p, ec);
    if (!ec) return resolved;
  }
  return p;
}

fs::path parent_dir(const fs::path& p) {
  fs::path dir = p.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

/// Throws unless `dir` exists, is a directory and is writable by this process.
void check_directory(const std::string& shown, const fs::path& dir) {
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) fail(shown, "directory '" + dir.string() + "' does not exist");
  if (!fs::is_directory(st)) fail(shown, "'" + dir.string() + "' is not a directory");
  if (::access(dir.c_str(), W_OK | X_OK) != 0) fail(shown, "cannot write: " + errno_text(errno));
}

fs::path temp_path_for(const fs::path& final_path) {
  std::string name = final_path.filename().string();
  const std::string ext = final_path.extension().string();
  if (name.size() > 200) name.resize(200);  // keep within NAME_MAX with the suffix added
  const std::string temp =
      "." + name + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(g_counter.fetch_add(1)) + ext;
  return parent_dir(final_path) / temp;
}

/// Same file: equal after weakly_canonical, or the same inode when both exist (hard links). Absolute first:
/// weakly_canonical leaves a relative path whose first component does not exist relative, so "a.exr" would not
/// match "sub/../a.exr".
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::path ca = fs::weakly_canonical(fs::absolute(fs::path(a), ea), ea);
  const fs::path cb = fs::weakly_canonical(fs::absolute(fs::path(b), eb), eb);
  if (!ea && !eb && ca == cb) return true;
  std::error_code ec;
  return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec) && !ec;
}

// ---- output groups ---------------------------------------------------------------------------------
struct Deferred {
  std::string target, temp, final_path;
  int slot;
};
std::mutex g_group_mutex;
int g_group_depth = 0;          // live OutputGroups; > 0: commits are deferred
bool g_group_poisoned = false;  // a joined group died uncommitted: the outer one must not commit
std::vector<Deferred> g_deferred;

void discard(std::vector<Deferred>& files) {
  for (const Deferred& d : files) {
    ::unlink(d.temp.c_str());
    unregister_temp(d.slot);
    retire_temp(d.temp);
  }
  files.clear();
}

/// A name for the backup of `final_path` (same directory), unused at the time of the call.
std::string backup_name(const std::string& final_path) {
  const fs::path p(final_path);
  std::string name = p.filename().string();
  if (name.size() > 200) name.resize(200);
  return (parent_dir(p) /
          ("." + name + ".bak-" + std::to_string(::getpid()) + "-" + std::to_string(g_counter.fetch_add(1))))
      .string();
}

/// Renames every file or none: see OutputGroup. Called with signals held.
void commit_all(std::vector<Deferred>& files) {
  struct Done {
    std::string backup;  // empty: the target did not exist
    bool renamed = false;
  };
  std::vector<Done> done(files.size());
  const auto roll_back = [&](std::size_t upto) {
    for (std::size_t j = 0; j < upto; ++j) {
      const Deferred& d = files[j];
      if (!done[j].backup.empty()) {
        ::rename(done[j].backup.c_str(), d.final_path.c_str());  // the old contents back
      } else if (done[j].renamed) {
        ::unlink(d.final_path.c_str());  // a new target disappears again
      }
    }
  };
  for (std::size_t i = 0; i < files.size(); ++i) {
    const Deferred& d = files[i];
    std::string why;
    struct stat st {};
    if (::lstat(d.final_path.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) {
      const std::string backup = backup_name(d.final_path);
      // A hard link keeps the target in place until it is replaced; where links are impossible, move it aside.
      if (::link(d.final_path.c_str(), backup.c_str()) == 0 || ::rename(d.final_path.c_str(), backup.c_str()) == 0)
        done[i].backup = backup;
      else
        why = "cannot keep a backup of the old file: " + errno_text(errno);
    }
    if (why.empty()) {
      if (::rename(d.temp.c_str(), d.final_path.c_str()) == 0)
        done[i].renamed = true;
      else
        why = errno_text(errno);
    }
    if (!why.empty()) {
      roll_back(i + 1);
      const std::string target = d.target;
      discard(files);
      fail(target, "cannot write: " + why);
    }
  }
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (!done[i].backup.empty()) ::unlink(done[i].backup.c_str());
    unregister_temp(files[i].slot);
    retire_temp(files[i].temp);
  }
  files.clear();
}

}  // namespace

AtomicOutput::AtomicOutput(std::string target) : target_(std::move(target)) {
  if (target_.empty()) fail("", "empty output path");
  if (target_.find('\0') != std::string::npos) fail(excerpt(target_, 200), "the path contains a NUL character");
  install_temp_cleanup_on_signal();
  if (is_live_temp(target_)) {
    // A writer handed the temp file of an AtomicOutput that a caller holds: write into it, the caller renames it.
    passthrough_ = true;
    final_path_ = temp_ = target_;
    xfsz_at_start_ = g_xfsz.load();
    return;
  }
  const fs::path final_path = resolve_target(target_);
  std::error_code ec;
  if (fs::is_directory(final_path, ec)) fail(target_, "is a directory");
  check_directory(target_, parent_dir(final_path));
  final_path_ = final_path.string();
  temp_ = temp_path_for(final_path).string();
  xfsz_at_start_ = g_xfsz.load();
  remember_temp(temp_, target_);
  slot_ = register_temp(temp_);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) {
    ::unlink(temp_.c_str());
    unregister_temp(slot_);
    if (!passthrough_) retire_temp(temp_);
  }
}

void AtomicOutput::commit() {
  if (committed_) return;
  const auto give_up = [this](const std::string& why) {
    ::unlink(temp_.c_str());
    fail(target_, "cannot write: " + why);
  };
  // fsync before rename: otherwise a crash shortly after may leave an empty file under the target's name.
  // It also reports a full disk that the writer's buffered writes did not.
  const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) give_up(errno_text(errno));
  const int sync_result = ::fsync(fd);
  const int sync_errno = errno;
  ::close(fd);
  if (sync_result != 0 && sync_errno != EINVAL && sync_errno != EROFS) give_up(errno_text(sync_errno));
  if (g_xfsz.load() != xfsz_at_start_) give_up(errno_text(EFBIG) + " (the file size limit, ulimit -f)");
  if (passthrough_) {
    committed_ = true;  // the AtomicOutput that made the temp file renames it
    return;
  }
  {
    std::lock_guard<std::mutex> lock(g_group_mutex);
    if (g_group_depth > 0) {
      g_deferred.push_back({target_, temp_, final_path_, slot_});
      committed_ = true;  // the group owns the temp file now
      slot_ = -1;
      return;
    }
  }
  if (::rename(temp_.c_str(), final_path_.c_str()) != 0) give_up(errno_text(errno));
  committed_ = true;
  unregister_temp(slot_);
  retire_temp(temp_);
  slot_ = -1;
}

OutputGroup::OutputGroup() {
  std::lock_guard<std::mutex> lock(g_group_mutex);
  outer_ = g_group_depth++ == 0;
  if (outer_) g_group_poisoned = false;
}

OutputGroup::~OutputGroup() {
  std::lock_guard<std::mutex> lock(g_group_mutex);
  --g_group_depth;
  if (committed_) return;
  if (outer_)
    discard(g_deferred);
  else
    g_group_poisoned = true;
}

void OutputGroup::commit() {
  if (committed_) return;
  if (!outer_) {
    committed_ = true;
    return;
  }
  std::vector<Deferred> files;
  {
    std::lock_guard<std::mutex> lock(g_group_mutex);
    files.swap(g_deferred);
    if (g_group_poisoned) {
      discard(files);
      fail("", "an output of the group was not written; nothing was committed");
    }
  }
  {
    const HeldSignals held;
    commit_all(files);
  }
  committed_ = true;
}

void check_output_path(const std::string& out, const std::vector<std::string>& inputs, bool force) {
  if (out.empty()) fail("", "empty output path");
  const fs::path final_path = resolve_target(out);
  std::error_code ec;
  if (fs::is_directory(final_path, ec)) fail(out, "is a directory");
  if (!force) {
    for (const std::string& in : inputs)
      if (same_file(out, in)) fail(out, "output path is the same as input " + in + "; pass --force to overwrite it");
  }
  check_directory(out, parent_dir(final_path));
}

std::string without_temp_names(const std::string& message) {
  std::vector<TempName> names;
  {
    std::lock_guard<std::mutex> lock(g_names_mutex);
    names = g_names;
  }
  // Longest first, so a temp name inside another (a writer handed a temp path) is translated after the outer one;
  // full paths before bare file names.
  std::sort(names.begin(), names.end(),
            [](const TempName& a, const TempName& b) { return a.temp.size() > b.temp.size(); });
  std::string out = message;
  for (const TempName& n : names) replace_all(out, n.temp, n.target);
  for (const TempName& n : names) replace_all(out, fs::path(n.temp).filename().string(), n.target);
  return out;
}

[[noreturn]] void fail_write(const std::string& target, int err) {
  fail(target, "cannot write: " + errno_text(err != 0 ? err : EIO));
}

// ---- AtomicOutputStream -------------------------------------------------------------------------------
namespace {

/// A buffered streambuf onto a file descriptor that keeps the errno of the first failed write.
class FdBuffer : public std::streambuf {
 public:
  explicit FdBuffer(int fd) : fd_(fd), buffer_(1 << 16) { setp(buffer_.data(), buffer_.data() + buffer_.size()); }
  int error() const { return error_; }

 protected:
  int_type overflow(int_type ch) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  bool drain() {
    const char* p = pbase();
    while (error_ == 0 && p < pptr()) {
      const ssize_t n = ::write(fd_, p, std::size_t(pptr() - p));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0)
        error_ = n < 0 ? errno : EIO;
      else
        p += n;
    }
    setp(buffer_.data(), buffer_.data() + buffer_.size());
    return error_ == 0;
  }
  int fd_;
  int error_ = 0;
  std::vector<char> buffer_;
};

}  // namespace

struct AtomicOutputStream::Impl {
  int fd = -1;
  std::unique_ptr<FdBuffer> buffer;
};

AtomicOutputStream::AtomicOutputStream(const AtomicOutput& output)
    : std::ostream(nullptr), impl_(std::make_unique<Impl>()), target_(output.target()) {
  impl_->fd = ::open(output.temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (impl_->fd < 0) fail_write(target_, errno);
  impl_->buffer = std::make_unique<FdBuffer>(impl_->fd);
  rdbuf(impl_->buffer.get());
}

AtomicOutputStream::~AtomicOutputStream() {
  if (impl_->fd >= 0) {
    impl_->buffer->pubsync();  // close() was skipped (an exception): the temp file is about to be removed anyway
    ::close(impl_->fd);
  }
  rdbuf(nullptr);
}

void AtomicOutputStream::close() {
  if (impl_->fd < 0) return;
  flush();
  const int fd = std::exchange(impl_->fd, -1);
  const int close_result = ::close(fd);
  const int close_errno = errno;
  if (impl_->buffer->error() != 0) fail_write(target_, impl_->buffer->error());
  if (!*this) fail_write(target_, EIO);
  if (close_result != 0 && close_errno != EINTR) fail_write(target_, close_errno);
}

void check_distinct_outputs(const std::vector<std::string>& outputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (same_file(outputs[j], outputs[i])) fail(outputs[i], "is the same file as the output " + outputs[j]);
}

void check_outputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs, bool force) {
  check_distinct_outputs(outputs);
  for (const std::string& out : outputs) check_output_path(out, inputs, force);
}

void install_temp_cleanup_on_signal() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction action {};
    action.sa_handler = cleanup_on_signal;
    action.sa_mask = cleanup_signals();  // one cleanup at a time
    action.sa_flags = 0;
    for (int sig = 1; sig < NSIG; ++sig)
      if (sigismember(&cleanup_signals(), sig) == 1) install_over_default(sig, action);
    // The file size limit: its default action kills the process with the temp file left behind. Counted instead,
    // the write fails with EFBIG, the writer reports it, and commit() refuses a file written meanwhile.
    struct sigaction xfsz {};
    xfsz.sa_handler = note_file_size_limit;
    sigemptyset(&xfsz.sa_mask);
    xfsz.sa_flags = SA_RESTART;
    install_over_default(SIGXFSZ, xfsz);
  });
}

}  // namespace envkit
