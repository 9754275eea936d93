#include <envkit/core/error.h>
#include <envkit/core/input_checks.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

namespace envkit {
namespace {

const char* kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

void check_mode(const std::string& path, mode_t mode) {
  if (S_ISREG(mode)) return;
  if (S_ISDIR(mode)) fail(path, "is a directory");
  fail(path, std::string("is ") + kind_of(mode) + ", not a regular file (envkit reads regular files only)");
}

std::uint64_t read_u64_file(const char* file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text == "max") return std::numeric_limits<std::uint64_t>::max();
  try {
    return std::stoull(text);
  } catch (const std::exception&) {
    return std::numeric_limits<std::uint64_t>::max();
  }
}

std::string gib(std::uint64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f GiB", static_cast<double>(bytes) / double(1 << 30));
  return buf;
}

}  // namespace

void require_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR) fail(path, "no such file");
    fail(path, std::string("cannot open: ") + std::strerror(errno));
  }
  check_mode(path, st.st_mode);
}

int open_regular_file(const std::string& path) {
  require_regular_file(path);
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) fail(path, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    check_mode(path, st.st_mode);
  }
  return fd;
}

std::vector<unsigned char> read_regular_file(const std::string& path, std::uint64_t max_bytes) {
  const int fd = open_regular_file(path);
  struct stat st {};
  ::fstat(fd, &st);
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes) {
    ::close(fd);
    fail(path, "file too large: " + std::to_string(size) + " bytes (limit " + std::to_string(max_bytes) + ")");
  }
  std::vector<unsigned char> bytes;
  try {
    check_memory_for(path, "reading the file", size);
    bytes.resize(static_cast<std::size_t>(size));
  } catch (...) {
    ::close(fd);
    throw;
  }
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      fail(path, std::string("cannot read: ") + std::strerror(err));
    }
    if (n == 0) break;  // shrank while being read: the decoder reports the truncation
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  bytes.resize(done);
  return bytes;
}

std::uint64_t available_memory_bytes() {
  std::uint64_t available = std::numeric_limits<std::uint64_t>::max();
  if (std::FILE* f = std::fopen("/proc/meminfo", "r")) {
    char key[64];
    unsigned long long kb = 0;
    std::uint64_t mem = 0, swap = 0;
    bool found = false;
    while (std::fscanf(f, "%63s %llu kB", key, &kb) == 2) {
      if (std::strcmp(key, "MemAvailable:") == 0) mem = kb * 1024ull, found = true;
      if (std::strcmp(key, "SwapFree:") == 0) swap = kb * 1024ull;
    }
    std::fclose(f);
    if (found) available = mem + swap;
  }
  const std::uint64_t cg_max = read_u64_file("/sys/fs/cgroup/memory.max");
  if (cg_max != std::numeric_limits<std::uint64_t>::max()) {
    const std::uint64_t used = read_u64_file("/sys/fs/cgroup/memory.current");
    available = std::min(available, used < cg_max ? cg_max - used : 0);
  }
  for (int resource : {RLIMIT_AS, RLIMIT_DATA}) {
    rlimit lim{};
    if (::getrlimit(resource, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY)
      available = std::min<std::uint64_t>(available, lim.rlim_cur);
  }
  return available;
}

void check_memory_for(const std::string& path, const std::string& what, std::uint64_t bytes) {
  const std::uint64_t available = available_memory_bytes();
  if (bytes > available) fail(path, what + " needs " + gib(bytes) + " of memory, " + gib(available) + " available");
}

}  // namespace envkit
