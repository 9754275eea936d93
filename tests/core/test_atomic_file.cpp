// Tests for atomic_file.h: temp + rename writes, cleanup on failure and on signals, output-path checks.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using envkit::AtomicOutput;
using envkit::Error;

namespace {

class AtomicFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("envkit_atomic_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    return names;
  }
  fs::path dir_;
};

void write_text(const std::string& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << file;
}

std::string read_text(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Runs `body` in a child process that has dropped root privileges (root ignores directory permissions),
/// returning its exit status. `body` returns the exit code.
int run_unprivileged(const std::function<int()>& body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(90);
    ::_exit(body());
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 100 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

/// The process HandlerInstalledEarlierStaysInCharge starts: installs its own SIGINT handler before envkit installs
/// anything, writes `target` through an AtomicOutput with a SIGINT in the middle, and exits 0 if its handler ran and
/// the output was committed.
int earlier_handler_child(const std::string& target) {
  static volatile sig_atomic_t got = 0;
  struct sigaction own {};
  own.sa_handler = [](int) { got = 1; };
  sigemptyset(&own.sa_mask);
  ::sigaction(SIGINT, &own, nullptr);
  AtomicOutput out(target);  // installs the cleanup handlers
  { std::ofstream(out.temp_path()) << "data"; }
  ::raise(SIGINT);
  if (!got) return 1;
  if (!fs::exists(out.temp_path())) return 2;
  out.commit();
  return fs::exists(target) ? 0 : 3;
}

// Before main(): the copy of this binary that HandlerInstalledEarlierStaysInCharge starts runs only the child.
const int kEarlierHandlerChild = [] {
  if (const char* target = std::getenv("ENVKIT_TEST_EARLIER_HANDLER")) ::_exit(earlier_handler_child(target));
  return 0;
}();

bool starts_with(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

}  // namespace

TEST_F(AtomicFileTest, TempNameSitsNextToTargetAndKeepsExtension) {
  AtomicOutput out(path("probe.exr"));
  const fs::path temp(out.temp_path());
  EXPECT_EQ(temp.parent_path(), dir_);
  EXPECT_TRUE(starts_with(temp.filename().string(), ".probe.exr.tmp-" + std::to_string(::getpid()) + "-")) << temp;
  EXPECT_EQ(temp.extension(), ".exr");
  AtomicOutput other(path("probe.exr"));
  EXPECT_NE(other.temp_path(), out.temp_path());
  EXPECT_FALSE(fs::exists(temp)) << "nothing is created before the caller writes";
}

TEST_F(AtomicFileTest, CommitRenamesTempOverTarget) {
  const std::string target = path("out.txt");
  write_text(target, "old");
  {
    AtomicOutput out(target);
    write_text(out.temp_path(), "new contents");
    EXPECT_EQ(read_text(target), "old") << "target untouched until commit";
    out.commit();
    EXPECT_TRUE(out.committed());
    EXPECT_FALSE(fs::exists(out.temp_path()));
  }
  EXPECT_EQ(read_text(target), "new contents");
  EXPECT_EQ(listing(), std::vector<std::string>{"out.txt"});
}

TEST_F(AtomicFileTest, ThrowingWriteLeavesNeitherTargetNorTemp) {
  const std::string target = path("result.exr");
  std::string temp;
  EXPECT_THROW(
      {
        AtomicOutput out(target);
        temp = out.temp_path();
        write_text(temp, "partial");
        throw std::runtime_error("writer failed");
      },
      std::runtime_error);
  EXPECT_FALSE(fs::exists(target));
  EXPECT_FALSE(fs::exists(temp));
  EXPECT_TRUE(listing().empty());
}

TEST_F(AtomicFileTest, FailedWriteKeepsExistingTarget) {
  const std::string target = path("keep.txt");
  write_text(target, "precious");
  {
    AtomicOutput out(target);
    write_text(out.temp_path(), "half-writ");
  }  // no commit
  EXPECT_EQ(read_text(target), "precious");
  EXPECT_EQ(listing(), std::vector<std::string>{"keep.txt"});
}

TEST_F(AtomicFileTest, CommitWithoutTempFileFailsWithTargetInMessage) {
  const std::string target = path("never.txt");
  AtomicOutput out(target);
  try {
    out.commit();
    FAIL() << "commit without a temp file must throw";
  } catch (const Error& e) {
    EXPECT_TRUE(starts_with(e.what(), target + ": cannot write: ")) << e.what();
  }
  EXPECT_FALSE(fs::exists(target));
}

TEST_F(AtomicFileTest, SymlinkTargetReplacesThePointee) {
  const std::string real = path("real.txt");
  const std::string link = path("link.txt");
  write_text(real, "old");
  fs::create_symlink(real, link);
  AtomicOutput out(link);
  write_text(out.temp_path(), "new");
  out.commit();
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(read_text(real), "new");
}

TEST_F(AtomicFileTest, MissingDirectoryIsReported) {
  const std::string target = path("no/such/dir/out.exr");
  try {
    AtomicOutput out(target);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_TRUE(starts_with(msg, target + ": directory '")) << msg;
    EXPECT_NE(msg.find("does not exist"), std::string::npos) << msg;
  }
}

TEST_F(AtomicFileTest, CheckOutputPathDetectsSameFileUnderOtherSpellings) {
  const std::string input = path("in.exr");
  write_text(input, "x");
  const std::string expected = input + ": output path is the same as input " + input + "; pass --force to overwrite it";
  try {
    envkit::check_output_path(input, {input}, false);
    FAIL() << "same path must be refused";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), expected);
  }
  // Other spellings of the same file: dot-dot, ./, a relative path, a hard link.
  fs::create_directories(dir_ / "sub");
  const std::string dotdot = (dir_ / "sub" / ".." / "." / "in.exr").string();
  const std::string relative = fs::relative(fs::path(input), fs::current_path()).string();
  fs::create_hard_link(input, dir_ / "hard.exr");
  for (const std::string& spelling : {dotdot, relative, path("hard.exr")}) {
    EXPECT_THROW(envkit::check_output_path(spelling, {input}, false), Error) << spelling;
    EXPECT_NO_THROW(envkit::check_output_path(spelling, {input}, true)) << "--force allows it: " << spelling;
  }
  EXPECT_NO_THROW(envkit::check_output_path(path("other.exr"), {input}, false));
  EXPECT_NO_THROW(envkit::check_output_path(path("new.exr"), {path("missing-input.exr")}, false));
}

TEST_F(AtomicFileTest, CheckOutputPathRejectsMissingAndDirectoryTargets) {
  EXPECT_THROW(envkit::check_output_path(path("nope/out.exr"), {}, false), Error);
  try {
    envkit::check_output_path(dir_.string(), {}, false);
    FAIL() << "a directory is not an output file";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), dir_.string() + ": is a directory");
  }
}

TEST_F(AtomicFileTest, UnwritableDirectoryIsReported) {
  fs::create_directories(dir_ / "ro");
  fs::permissions(dir_ / "ro", fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                                   fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  const std::string target = (dir_ / "ro" / "out.exr").string();
  const std::string expected = target + ": cannot write: Permission denied";
  const auto check = [&]() -> int {
    try {
      envkit::check_output_path(target, {}, false);
      return 1;
    } catch (const Error& e) {
      if (std::string(e.what()) != expected) return 2;
    }
    try {
      AtomicOutput out(target);
      return 3;
    } catch (const Error& e) {
      if (std::string(e.what()) != expected) return 4;
    }
    return 0;
  };
  if (::geteuid() == 0) {
    // Root bypasses permission bits: check as an unprivileged user in a child process.
    fs::permissions(dir_, fs::perms::others_exec | fs::perms::others_read, fs::perm_options::add);
    EXPECT_EQ(run_unprivileged(check), 0) << "1/3: no error, 2/4: wrong message; expected \"" << expected << "\"";
  } else {
    EXPECT_EQ(check(), 0) << "1/3: no error, 2/4: wrong message; expected \"" << expected << "\"";
  }
}

TEST_F(AtomicFileTest, SignalRemovesLiveTempFiles) {
  const std::string target = path("interrupted.exr");
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    envkit::install_temp_cleanup_on_signal();
    AtomicOutput out(target);
    { std::ofstream(out.temp_path()) << "long write in progress"; }
    const std::string msg = out.temp_path() + "\n";
    if (::write(fds[1], msg.data(), msg.size()) != static_cast<ssize_t>(msg.size())) ::_exit(3);
    for (;;) ::pause();  // "still writing" until the signal arrives
  }
  ::close(fds[1]);
  std::string temp;
  char c;
  while (::read(fds[0], &c, 1) == 1 && c != '\n') temp += c;
  ::close(fds[0]);
  ASSERT_FALSE(temp.empty());
  EXPECT_TRUE(fs::exists(temp)) << "the child wrote its temp file";
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "re-raised with the default action";
  EXPECT_FALSE(fs::exists(temp)) << "temp file removed by the handler";
  EXPECT_FALSE(fs::exists(target));
}

TEST_F(AtomicFileTest, IgnoredSignalStaysIgnored) {
  // nohup: SIGHUP ignored. Installing the cleanup must not turn it into "delete my output and die".
  const std::string target = path("nohup.exr");
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGHUP, SIG_IGN);
    envkit::install_temp_cleanup_on_signal();
    AtomicOutput out(target);
    { std::ofstream(out.temp_path()) << "data"; }
    ::raise(SIGHUP);
    if (!fs::exists(out.temp_path())) ::_exit(1);
    out.commit();
    ::_exit(fs::exists(target) ? 0 : 2);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "the child was killed by the ignored signal";
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST_F(AtomicFileTest, OutputGroupCommitsEveryFileOrNone) {
  write_text(path("a.exr"), "old a");
  {
    // A writer that fails after others committed: nothing of the group appears, the old file is untouched.
    envkit::OutputGroup group;
    {
      AtomicOutput a(path("a.exr"));
      write_text(a.temp_path(), "new a");
      a.commit();
    }
    {
      AtomicOutput b(path("b.exr"));
      write_text(b.temp_path(), "new b");
      b.commit();
    }
    EXPECT_EQ(read_text(path("a.exr")), "old a") << "deferred until the group commits";
    EXPECT_FALSE(fs::exists(path("b.exr")));
  }  // destroyed uncommitted
  EXPECT_EQ(read_text(path("a.exr")), "old a");
  EXPECT_EQ(listing(), std::vector<std::string>{"a.exr"}) << "no temp file survives an uncommitted group";

  envkit::OutputGroup group;
  for (const char* name : {"a.exr", "b.exr", "c.exr"}) {
    AtomicOutput out(path(name));
    write_text(out.temp_path(), std::string("new ") + name);
    out.commit();
  }
  group.commit();
  EXPECT_EQ(read_text(path("a.exr")), "new a.exr");
  EXPECT_EQ(read_text(path("c.exr")), "new c.exr");
  std::vector<std::string> names = listing();
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"a.exr", "b.exr", "c.exr"})) << "no backup or temp file left";
}

TEST_F(AtomicFileTest, OutputGroupRollsBackWhenARenameFails) {
  write_text(path("a.exr"), "old a");
  envkit::OutputGroup group;
  {
    AtomicOutput a(path("a.exr"));
    write_text(a.temp_path(), "new a");
    a.commit();
    AtomicOutput b(path("b.exr"));
    write_text(b.temp_path(), "new b");
    b.commit();
  }
  // b.exr becomes a non-empty directory before the group commits: its rename fails after a.exr's succeeded.
  fs::create_directories(dir_ / "b.exr" / "x");
  try {
    group.commit();
    FAIL() << "the rename over a directory must fail";
  } catch (const Error& e) {
    EXPECT_TRUE(starts_with(e.what(), path("b.exr") + ": cannot write: ")) << e.what();
  }
  EXPECT_EQ(read_text(path("a.exr")), "old a") << "the committed file is rolled back to its old contents";
  std::vector<std::string> names = listing();
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"a.exr", "b.exr"})) << "no backup or temp file left";
}

TEST_F(AtomicFileTest, FileSizeLimitFailsTheCommitInsteadOfKillingTheProcess) {
  const std::string target = path("big.exr");
  const pid_t pid = ::fork();
  if (pid == 0) {
    AtomicOutput out(target);  // installs the SIGXFSZ handler
    const struct rlimit rl { 1024, 1024 };
    ::setrlimit(RLIMIT_FSIZE, &rl);
    std::ofstream(out.temp_path()) << std::string(8192, 'x');  // cut at 1024 bytes: EFBIG, SIGXFSZ
    try {
      out.commit();
      ::_exit(1);
    } catch (const Error& e) {
      if (std::string(e.what()) !=
          target + ": cannot write: " + std::strerror(EFBIG) + " (the file size limit, ulimit -f)")
        ::_exit(2);
    }
    ::_exit(fs::exists(target) || fs::exists(out.temp_path()) ? 3 : 0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: committed, 2: wrong message, 3: a file was left";
}

TEST_F(AtomicFileTest, MessagesNameTargetsNotTempFiles) {
  AtomicOutput out(path("sky.exr"));
  AtomicOutput bare(path("o_+X"));
  EXPECT_EQ(envkit::without_temp_names("Failed to write \"" + out.temp_path() + "\". File too large."),
            "Failed to write \"" + path("sky.exr") + "\". File too large.");
  EXPECT_EQ(envkit::without_temp_names(bare.temp_path() + ": no file extension"), path("o_+X") + ": no file extension");
  EXPECT_EQ(envkit::without_temp_names("plain message"), "plain message");
}

TEST_F(AtomicFileTest, MessagesNameTheTargetOnceWhateverFollowsTheTempName) {
  // A temp name followed by ':' (a writer's "<path>: cannot write") was turned into "u.ktx2.ktx2:".
  AtomicOutput ktx(path("u.ktx2"));
  EXPECT_EQ(envkit::without_temp_names(ktx.temp_path() + ": cannot write: No space left on device"),
            path("u.ktx2") + ": cannot write: No space left on device");
  EXPECT_EQ(envkit::without_temp_names("'" + ktx.temp_path() + "', then " + ktx.temp_path() + "."),
            "'" + path("u.ktx2") + "', then " + path("u.ktx2") + ".");
  // The bare file name (libraries that print only that) names the target too.
  EXPECT_EQ(envkit::without_temp_names(fs::path(ktx.temp_path()).filename().string() + ": short write"),
            path("u.ktx2") + ": short write");
  // A relative target keeps its spelling.
  AtomicOutput relative("irr.exr");
  EXPECT_EQ(envkit::without_temp_names(relative.temp_path() + ": cannot write"), "irr.exr: cannot write");
}

TEST_F(AtomicFileTest, WriterHandedATempPathWritesIntoIt) {
  // A tool stages its outputs itself and hands a writer the temp path: no second temp file, no second rename.
  AtomicOutput staged(path("irr.exr"));
  {
    AtomicOutput inner(staged.temp_path());
    EXPECT_EQ(inner.temp_path(), staged.temp_path());
    envkit::AtomicOutputStream os(inner);
    os << "irradiance";
    os.close();
    inner.commit();
    EXPECT_EQ(listing(), std::vector<std::string>{fs::path(staged.temp_path()).filename().string()});
  }
  staged.commit();
  EXPECT_EQ(read_text(path("irr.exr")), "irradiance");
  EXPECT_EQ(listing(), std::vector<std::string>{"irr.exr"});
}

TEST_F(AtomicFileTest, StreamReportsTheTargetAndTheCause) {
  const std::string target = path("s.csv");
  const pid_t pid = ::fork();
  if (pid == 0) {
    int code = 1;
    try {
      AtomicOutput out(target);  // installs the SIGXFSZ handler: the write fails with EFBIG
      const struct rlimit rl { 1024, 1024 };
      ::setrlimit(RLIMIT_FSIZE, &rl);
      envkit::AtomicOutputStream os(out);
      for (int i = 0; i < 1000; ++i) os << "0.123456789,0.987654321\n";
      os.close();
    } catch (const Error& e) {
      code = std::string(e.what()) == target + ": cannot write: " + std::strerror(EFBIG) ? 0 : 2;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: no error, 2: wrong message";
  EXPECT_TRUE(listing().empty()) << "the temp file is removed with its AtomicOutput";
}

TEST_F(AtomicFileTest, NulInTheTargetIsRefused) {
  const std::string target = path("a") + std::string(1, '\0') + "b.exr";
  try {
    AtomicOutput out(target);
    FAIL() << "a path with a NUL names another file once cut at the NUL";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("contains a NUL character"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("\\x00"), std::string::npos) << e.what();
  }
}

// Every signal a user can send that ends the process by default: temp files removed, the process still dies by
// that signal (exit status 128 + N in a shell).
TEST_F(AtomicFileTest, EveryTerminatingSignalRemovesLiveTempFiles) {
  for (int sig : {SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGPIPE, SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU,
                  SIGIO, SIGPWR, SIGRTMIN, SIGRTMAX}) {
    SCOPED_TRACE(strsignal(sig));
    const std::string target = path("interrupted.exr");
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::close(fds[0]);
      const struct rlimit no_core { 0, 0 };
      ::setrlimit(RLIMIT_CORE, &no_core);  // SIGQUIT dumps core by default
      AtomicOutput out(target);
      { std::ofstream(out.temp_path()) << "long write in progress"; }
      if (::write(fds[1], "x", 1) != 1) ::_exit(3);
      for (;;) ::pause();
    }
    ::close(fds[1]);
    char c;
    ASSERT_EQ(::read(fds[0], &c, 1), 1);
    ::close(fds[0]);
    ASSERT_EQ(listing().size(), 1u) << "the child wrote its temp file";
    ::kill(pid, sig);
    int status = 0;
    ::waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status;
    EXPECT_TRUE(listing().empty()) << "temp file removed by the handler";
  }
}

// A handler someone installed before (Python's SIGINT handler raises KeyboardInterrupt) stays in charge: the signal
// reaches it, the temp file is not pulled from under a write that goes on, and the output is committed. Run in a
// fresh copy of this binary (see kEarlierHandlerChild): in this process the cleanup handlers are installed already.
TEST_F(AtomicFileTest, HandlerInstalledEarlierStaysInCharge) {
  const std::string target = path("python.exr");
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setenv("ENVKIT_TEST_EARLIER_HANDLER", target.c_str(), 1);
    char self[] = "test_atomic_file";
    char* argv[] = {self, nullptr};
    ::execv("/proc/self/exe", argv);
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: the earlier handler did not run, 2: temp file removed, 3: not committed";
  EXPECT_TRUE(fs::exists(target));
}
