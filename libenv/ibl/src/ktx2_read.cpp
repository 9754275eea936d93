// Reading back the KTX2 files write_ktx2 writes (uncompressed RGBA16F/RGBA32F/B10G11R11/E5B9G9R9), for the viewer
// test's reference shading and other consumers that want the exact texels a GPU gets.
#include <Imath/half.h>
#include <envkit/core/error.h>
#include <envkit/ibl/ktx2.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>

namespace envkit {

namespace {

std::uint32_t u32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
std::uint64_t u64(const std::string& b, std::size_t at) {
  std::uint64_t v;
  std::memcpy(&v, b.data() + at, 8);
  return v;
}

GpuFormat format_of(std::uint32_t vk, const std::string& path) {
  for (GpuFormat f : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9})
    if (vk_format(f) == vk) return f;
  fail(path, "vkFormat " + std::to_string(vk) + " is not one of rgba16f, rgba32f, rg11b10f, rgb9e5");
}

// Decodes texel t of a level's bytes into rgba.
void decode(const char* p, GpuFormat format, float rgba[4]) {
  rgba[3] = 1.0f;
  switch (format) {
    case GpuFormat::Rgba16f:
      for (int c = 0; c < 4; ++c) {
        std::uint16_t bits;
        std::memcpy(&bits, p + 2 * c, 2);
        Imath::half h;
        h.setBits(bits);
        rgba[c] = float(h);
      }
      break;
    case GpuFormat::Rgba32f:
      std::memcpy(rgba, p, 16);
      break;
    case GpuFormat::B10G11R11: {
      std::uint32_t w;
      std::memcpy(&w, p, 4);
      unpack_b10g11r11(w, rgba);
      break;
    }
    case GpuFormat::E5B9G9R9: {
      std::uint32_t w;
      std::memcpy(&w, p, 4);
      unpack_e5b9g9r9(w, rgba);
      break;
    }
  }
}

}  // namespace

Ktx2Texels read_ktx2(const std::string& path) {
  const GpuTextureInfo info = read_gpu_texture_info(path);  // identifier, header and key/value data
  if (info.container != "ktx2") fail(path, "not a KTX2 file");
  std::ifstream in(path, std::ios::binary);
  const std::string b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Ktx2Texels out;
  out.format = format_of(u32(b, 12), path);
  out.faces = info.faces;
  out.key_values = info.key_values;
  if (out.faces != 1 && out.faces != 6) fail(path, "faceCount " + std::to_string(out.faces) + " is not 1 or 6");
  if (info.width < 1 || info.width != info.height) fail(path, "levels are not square");
  // Bounded before any size arithmetic: 6 faces of 32768^2 RGBA32F texels are already 96 GiB.
  if (info.width > 32768) fail(path, "levels of " + std::to_string(info.width) + " texels are larger than 32768");
  if (u32(b, 28) > 1 || u32(b, 32) != 0) fail(path, "array textures are not supported");
  if (u32(b, 44) != 0) fail(path, "supercompressed levels are not supported");
  const int levels = info.levels;
  if (levels > 16 || b.size() < 80 + std::size_t(levels) * 24) fail(path, "truncated level index");
  const std::size_t bytes = std::size_t(gpu_format_bytes(out.format));
  for (int m = 0; m < levels; ++m) {
    const int n = std::max(1, info.width >> m);
    const std::uint64_t offset = u64(b, 80 + 24 * std::size_t(m)), length = u64(b, 88 + 24 * std::size_t(m));
    const std::size_t want = std::size_t(out.faces) * n * n * bytes;
    if (length != want)
      fail(path, "level " + std::to_string(m) + " holds " + std::to_string(length) + " bytes, expected " +
                     std::to_string(want));
    if (offset > b.size() || length > b.size() - offset) fail(path, "level " + std::to_string(m) + " beyond the end");
    Image level(n, n * out.faces, 4);
    level.channel_names = {"R", "G", "B", "A"};
    level.alpha_channel = 3;
    for (std::size_t t = 0; t < std::size_t(n) * n * out.faces; ++t)
      decode(b.data() + offset + t * bytes, out.format, level.pixels.data() + 4 * t);
    out.levels.push_back(std::move(level));
  }
  return out;
}

}  // namespace envkit
