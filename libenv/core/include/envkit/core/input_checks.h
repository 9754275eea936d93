#pragma once
/// @file input_checks.h
/// Checks every reader of envkit makes before it opens or allocates anything for an input file.
///
/// Inputs must be regular files: a FIFO or a terminal would block a reader until killed, /dev/zero or /dev/urandom
/// would feed it without end, and a directory has no bytes. Readers call require_regular_file() before opening (open()
/// itself blocks on a FIFO without a writer) and open_regular_file() to get a descriptor that is re-checked with fstat
/// (the path may have been swapped in between).
///
/// Buffers whose size comes from a file header are checked against the memory the machine can give (check_memory_for())
/// before they are allocated, so a plausible-looking but huge header is refused with the file and the size named
/// instead of ending in an allocation failure or the OOM killer.
#include <cstdint>
#include <string>
#include <vector>

namespace envkit {

/// Throws Error("<path>: no such file"), Error("<path>: is a directory") or Error("<path>: is a FIFO|character
/// device|block device|socket, not a regular file") unless `path` (symlinks followed) is a regular file.
void require_regular_file(const std::string& path);

/// require_regular_file(), then open(O_RDONLY | O_NONBLOCK) (never blocks) and fstat the descriptor. Returns the
/// descriptor (the caller closes it); throws Error("<path>: cannot open: <strerror>").
int open_regular_file(const std::string& path);

/// The whole of a regular file, at most `max_bytes` (Error("<path>: file too large: ...") beyond).
std::vector<unsigned char> read_regular_file(const std::string& path, std::uint64_t max_bytes);

/// Bytes this process can still allocate and touch without swapping out others: MemAvailable (+ SwapFree) from
/// /proc/meminfo, capped by a cgroup v2 memory.max and by RLIMIT_AS / RLIMIT_DATA. UINT64_MAX when nothing is known.
std::uint64_t available_memory_bytes();

/// Throws Error("<path>: <what> needs <X> GiB of memory, <Y> GiB available") when `bytes` exceeds
/// available_memory_bytes(). `what` describes the buffer, e.g. "image 65536x32768 (3 channels, float)".
void check_memory_for(const std::string& path, const std::string& what, std::uint64_t bytes);

}  // namespace envkit
