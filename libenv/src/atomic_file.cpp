#include <envkit/atomic_file.h>
#include <envkit/error.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <mutex>

namespace envkit {
namespace fs = std::filesystem;

namespace {

// ---- registry of live temp files, read by the signal handler -------------------------------------------
// Fixed storage and lock-free atomics only: the handler may run at any point, on any thread.
constexpr int kSlots = 64;
constexpr std::size_t kMaxPath = 4096;
enum SlotState : int { kFree = 0, kBusy = 1, kLive = 2 };

struct Slot {
  std::atomic<int> state{kFree};
  char path[kMaxPath];
};
std::array<Slot, kSlots> g_slots;
static_assert(std::atomic<int>::is_always_lock_free, "signal handler needs lock-free atomics");

int register_temp(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (g_slots[i].state.compare_exchange_strong(expected, kBusy)) {
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

constexpr std::array<int, 3> kSignals = {SIGINT, SIGTERM, SIGHUP};
std::array<struct sigaction, kSignals.size()> g_previous{};

extern "C" void cleanup_on_signal(int sig) {
  const int saved_errno = errno;
  for (auto& slot : g_slots)
    if (slot.state.load() == kLive) ::unlink(slot.path);  // async-signal-safe
  // Restore whatever was there before and re-raise: delivered when this handler returns.
  for (std::size_t i = 0; i < kSignals.size(); ++i)
    if (kSignals[i] == sig) ::sigaction(sig, &g_previous[i], nullptr);
  errno = saved_errno;
  ::raise(sig);
}

std::atomic<unsigned long> g_counter{0};

std::string errno_text(int err) { return std::strerror(err); }

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
  const std::string temp = "." + name + ".tmp-" + std::to_string(::getpid()) + "-" +
                           std::to_string(g_counter.fetch_add(1)) + ext;
  return parent_dir(final_path) / temp;
}

/// Same file: equal after weakly_canonical, or the same inode when both exist (hard links).
bool same_file(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::path ca = fs::weakly_canonical(fs::path(a), ea);
  const fs::path cb = fs::weakly_canonical(fs::path(b), eb);
  if (!ea && !eb && ca == cb) return true;
  std::error_code ec;
  return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec) && !ec;
}

}  // namespace

AtomicOutput::AtomicOutput(std::string target) : target_(std::move(target)) {
  if (target_.empty()) fail("", "empty output path");
  const fs::path final_path = resolve_target(target_);
  std::error_code ec;
  if (fs::is_directory(final_path, ec)) fail(target_, "is a directory");
  check_directory(target_, parent_dir(final_path));
  final_path_ = final_path.string();
  temp_ = temp_path_for(final_path).string();
  slot_ = register_temp(temp_);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) ::unlink(temp_.c_str());
  unregister_temp(slot_);
}

void AtomicOutput::commit() {
  if (committed_) return;
  const auto give_up = [this](const std::string& why) {
    ::unlink(temp_.c_str());
    fail(target_, "cannot write: " + why);
  };
  // fsync before rename: otherwise a crash shortly after may leave an empty file under the target's name.
  const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) give_up(errno_text(errno));
  const int sync_result = ::fsync(fd);
  const int sync_errno = errno;
  ::close(fd);
  if (sync_result != 0 && sync_errno != EINVAL && sync_errno != EROFS) give_up(errno_text(sync_errno));
  if (::rename(temp_.c_str(), final_path_.c_str()) != 0) give_up(errno_text(errno));
  committed_ = true;
  unregister_temp(slot_);
  slot_ = -1;
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

void install_temp_cleanup_on_signal() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction action {};
    action.sa_handler = cleanup_on_signal;
    sigemptyset(&action.sa_mask);
    for (int sig : kSignals) sigaddset(&action.sa_mask, sig);  // one cleanup at a time
    action.sa_flags = 0;
    for (std::size_t i = 0; i < kSignals.size(); ++i) {
      ::sigaction(kSignals[i], nullptr, &g_previous[i]);
      // An ignored signal (nohup's SIGHUP) must stay ignored: cleaning up would kill a write that goes on.
      if (g_previous[i].sa_handler == SIG_IGN && !(g_previous[i].sa_flags & SA_SIGINFO)) continue;
      ::sigaction(kSignals[i], &action, nullptr);
    }
  });
}

}  // namespace envkit
