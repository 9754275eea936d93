#pragma once
/// @file cli_support.h
/// Running the built command-line tools from tests: the command's exit code, stdout and stderr (captured
/// through files, so both streams are complete and separate).
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace envkit::test {

struct CommandResult {
  int code = -1;  ///< exit status; 128 + N when killed by signal N
  std::string out, err;

  /// Non-empty lines of stderr.
  std::vector<std::string> err_lines() const {
    std::vector<std::string> lines;
    std::istringstream in(err);
    for (std::string line; std::getline(in, line);)
      if (!line.empty()) lines.push_back(line);
    return lines;
  }
};

/// Single-quotes `s` for /bin/sh.
inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Runs `program` with `args` (each quoted), stdout and stderr redirected to files in `capture_dir`.
inline CommandResult run_command(const std::string& program, const std::vector<std::string>& args,
                                 const std::filesystem::path& capture_dir) {
  const auto out = capture_dir / "cmd.stdout", err = capture_dir / "cmd.stderr";
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "literal" + std::string&&.
  std::string command = shell_quote(program);
  for (const auto& a : args) command.append(" ").append(shell_quote(a));
  command.append(" >").append(shell_quote(out.string())).append(" 2>").append(shell_quote(err.string()));
  command.append(" </dev/null");
  const int status = std::system(command.c_str());
  CommandResult r;
  r.code = status == -1 ? -1 : WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

/// Runs one of envkit's built tools (bin/<tool> of the build tree).
inline CommandResult run_tool(const std::string& tool, const std::vector<std::string>& args,
                              const std::filesystem::path& capture_dir) {
  return run_command(std::string(ENVKIT_BIN_DIR) + "/" + tool, args, capture_dir);
}

}  // namespace envkit::test
