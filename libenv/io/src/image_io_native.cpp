#include "image_io_native.h"

#include <envkit/core/error.h>
#include <envkit/core/input_checks.h>
#include <envkit/io/image_codecs.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>

namespace envkit::detail {
namespace {

/// Reads exactly `n` bytes at `offset`; false when the file ends first.
bool read_at(int fd, void* out, std::size_t n, std::uint64_t offset) {
  auto* p = static_cast<unsigned char*>(out);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    p += got, n -= static_cast<std::size_t>(got), offset += static_cast<std::uint64_t>(got);
  }
  return true;
}

struct Fd {
  int fd;
  ~Fd() { ::close(fd); }
};

NativeRead read_radiance(const std::string& path, const std::function<void(int, int, int)>& check_size) {
  // The whole file is read first: new-style scanlines are located in it, then decoded in parallel.
  const std::vector<unsigned char> bytes = read_regular_file(path, std::numeric_limits<std::uint64_t>::max());
  const RadianceHeader h = parse_radiance_header(bytes, path);
  check_size(h.width, h.height, 3);
  NativeRead r;
  r.format = "hdr";
  r.xyze = h.xyze;
  r.pixel_type = h.xyze ? "xyze" : "rgbe";
  r.image = decode_radiance(bytes, h, path);
  for (const auto& [key, value] : h.variables) r.image.metadata[key] = value;
  if (h.exposure != 1.0) r.notes.push_back("EXPOSURE " + std::to_string(h.exposure) + " divided out");
  if (h.colorcorr != std::array<double, 3>{1, 1, 1}) r.notes.push_back("COLORCORR divided out");
  if (!h.primaries.empty()) r.notes.push_back("PRIMARIES line ignored: working-space primaries assumed");
  return r;
}

NativeRead read_pfm(const std::string& path, const std::function<void(int, int, int)>& check_size) {
  Fd file{open_regular_file(path)};
  unsigned char head[256];
  const ssize_t n = ::pread(file.fd, head, sizeof head, 0);
  if (n < 0) fail(path, std::string("cannot read: ") + std::strerror(errno));
  const PfmHeader h = parse_pfm_header({head, static_cast<std::size_t>(n)}, path);
  check_size(h.width, h.height, h.channels);
  struct stat st {};
  ::fstat(file.fd, &st);
  if (static_cast<std::uint64_t>(st.st_size) < h.data_offset + h.data_bytes())
    fail(path, "cannot read pixels (truncated or corrupt file?): " + std::to_string(h.data_bytes()) +
                   " bytes of pixels expected, " +
                   std::to_string(st.st_size > static_cast<off_t>(h.data_offset)
                                      ? st.st_size - static_cast<off_t>(h.data_offset)
                                      : 0) +
                   " found");
  FloatBuffer data(h.data_bytes() / sizeof(float));
  if (!read_at(file.fd, data.data(), h.data_bytes(), h.data_offset))
    fail(path,
         "cannot read pixels (truncated or corrupt file?): the file "
         "ended early");
  NativeRead r;
  r.format = "pfm";
  r.pixel_type = "float";
  r.image = decode_pfm(std::move(data), h);
  if (h.scale != 1.0) r.notes.push_back("PFM scale " + std::to_string(h.scale) + " ignored");
  return r;
}

void write_bytes(const std::string& path, const std::string& file, const std::vector<unsigned char>& head,
                 const void* body, std::size_t body_bytes) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> out(std::fopen(file.c_str(), "wb"), &std::fclose);
  if (!out) fail(path, std::string("cannot write: ") + std::strerror(errno));
  bool ok = std::fwrite(head.data(), 1, head.size(), out.get()) == head.size();
  ok = ok && (body_bytes == 0 || std::fwrite(body, 1, body_bytes, out.get()) == body_bytes);
  ok = ok && std::fflush(out.get()) == 0;
  const int err = errno;
  if (std::fclose(out.release()) != 0 || !ok)
    fail(path, std::string("cannot write: ") + (err ? std::strerror(err) : "write error (disk full?)"));
}

}  // namespace

NativeFormat sniff_native_format(const std::string& path) {
  Fd file{open_regular_file(path)};
  unsigned char head[3] = {0, 0, 0};
  const ssize_t n = ::pread(file.fd, head, sizeof head, 0);
  const std::span<const unsigned char> bytes(head, n > 0 ? static_cast<std::size_t>(n) : 0);
  if (looks_like_radiance(bytes)) return NativeFormat::Radiance;
  if (looks_like_pfm(bytes)) return NativeFormat::Pfm;
  return NativeFormat::None;
}

NativeRead read_native(const std::string& path, NativeFormat format,
                       const std::function<void(int, int, int)>& check_size) {
  return format == NativeFormat::Radiance ? read_radiance(path, check_size) : read_pfm(path, check_size);
}

void write_radiance_file(const std::string& path, const std::string& file, const Image& data,
                         const std::map<std::string, std::string>& variables) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> out(std::fopen(file.c_str(), "wb"), &std::fclose);
  if (!out) fail(path, std::string("cannot write: ") + std::strerror(errno));
  bool ok = true;
  encode_radiance(data, variables,
                  [&](const unsigned char* p, std::size_t n) { ok = ok && std::fwrite(p, 1, n, out.get()) == n; });
  ok = ok && std::fflush(out.get()) == 0;
  const int err = errno;
  if (std::fclose(out.release()) != 0 || !ok)
    fail(path, std::string("cannot write: ") + (err ? std::strerror(err) : "write error (disk full?)"));
}

void write_pfm_file(const std::string& path, const std::string& file, const Image& data) {
  static_assert(std::endian::native == std::endian::little, "the PFM writer writes the host's floats");
  // PFM rows go bottom to top: a flipped copy is written in one call.
  const std::size_t row = static_cast<std::size_t>(data.width) * static_cast<std::size_t>(data.channels);
  FloatBuffer flipped(data.pixels.size());
  for (int y = 0; y < data.height; ++y)
    std::memcpy(flipped.data() + static_cast<std::size_t>(data.height - 1 - y) * row, data.at(0, y),
                row * sizeof(float));
  write_bytes(path, file, encode_pfm_header(data), flipped.data(), flipped.size() * sizeof(float));
}

}  // namespace envkit::detail
