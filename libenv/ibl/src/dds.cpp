#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/ibl/dds.h>

#include <cerrno>
#include <cstring>
#include <fstream>

namespace envkit {

namespace {

void put32(std::vector<std::uint8_t>& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(v >> (8 * i)));
}

}  // namespace

ClampReport write_dds(const std::string& path, const std::vector<const Image*>& levels, const DdsOptions& options) {
  if (levels.empty()) fail(path, "no levels to write");
  if (options.faces != 1 && options.faces != 6) fail(path, "a DDS texture here has 1 or 6 faces");
  const int width = levels[0]->width, height = levels[0]->height / options.faces;
  if (options.faces == 6 && levels[0]->height != 6 * width) fail(path, "cube levels must be N x 6N vertical strips");
  for (std::size_t m = 0; m < levels.size(); ++m) {
    const int w = std::max(1, width >> m), h = std::max(1, height >> m);
    if (levels[m]->width != w || levels[m]->height != h * options.faces)
      fail(path, "level " + std::to_string(m) + " has the wrong size");
  }
  const int bytes = gpu_format_bytes(options.format);
  std::vector<std::uint8_t> f = {'D', 'D', 'S', ' '};
  constexpr std::uint32_t kCaps = 0x1, kHeight = 0x2, kWidth = 0x4, kPitch = 0x8, kPixelFormat = 0x1000,
                          kMipMapCount = 0x20000;
  put32(f, 124);
  put32(f, kCaps | kHeight | kWidth | kPitch | kPixelFormat | kMipMapCount);
  put32(f, std::uint32_t(height));
  put32(f, std::uint32_t(width));
  put32(f, std::uint32_t(width * bytes));  // pitch of level 0
  put32(f, 0);                             // depth
  put32(f, std::uint32_t(levels.size()));
  for (int i = 0; i < 11; ++i) put32(f, 0);  // reserved
  // DDS_PIXELFORMAT: size 32, DDPF_FOURCC, "DX10".
  put32(f, 32);
  put32(f, 0x4);
  f.insert(f.end(), {'D', 'X', '1', '0'});
  for (int i = 0; i < 5; ++i) put32(f, 0);
  constexpr std::uint32_t kTexture = 0x1000, kComplex = 0x8, kMipmap = 0x400000;
  put32(f, kTexture | (levels.size() > 1 || options.faces == 6 ? kComplex : 0) | (levels.size() > 1 ? kMipmap : 0));
  put32(f, options.faces == 6 ? 0x200u | 0xFC00u : 0u);  // DDSCAPS2_CUBEMAP | all six faces
  put32(f, 0);
  put32(f, 0);
  put32(f, 0);
  // DDS_HEADER_DXT10
  put32(f, dxgi_format(options.format));
  put32(f, 3);                             // D3D10_RESOURCE_DIMENSION_TEXTURE2D
  put32(f, options.faces == 6 ? 0x4 : 0);  // DDS_RESOURCE_MISC_TEXTURECUBE
  put32(f, 1);                             // arraySize (cubes count one array element of six faces)
  put32(f, 0);                             // alpha mode unknown
  std::vector<std::vector<std::uint8_t>> packed;
  ClampReport clamped;
  for (const Image* level : levels) {
    packed.push_back(pack_texels(*level, options.format));
    clamped.add(count_clamped(*level, options.format));
  }
  AtomicOutput out(path);
  {
    AtomicOutputStream os(out);
    os.write(reinterpret_cast<const char*>(f.data()), std::streamsize(f.size()));
    for (int face = 0; face < options.faces; ++face)  // each face's whole mip chain, then the next face
      for (std::size_t m = 0; m < levels.size(); ++m) {
        const std::size_t face_bytes = packed[m].size() / std::size_t(options.faces);
        os.write(reinterpret_cast<const char*>(packed[m].data() + face_bytes * face), std::streamsize(face_bytes));
      }
    os.close();
  }
  out.commit();
  return clamped;
}

}  // namespace envkit
