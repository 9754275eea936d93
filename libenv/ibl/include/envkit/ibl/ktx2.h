#pragma once
/// @file ktx2.h
/// GPU texel formats for real-time IBL outputs, and a KTX 2.0 writer (Khronos KTX File Format Specification 2.0).
///
/// Formats (Vulkan / DXGI numbers):
///   Rgba16f    VK_FORMAT_R16G16B16A16_SFLOAT 97,   DXGI_FORMAT_R16G16B16A16_FLOAT 10, 8 bytes per texel
///   Rgba32f    VK_FORMAT_R32G32B32A32_SFLOAT 109,  DXGI_FORMAT_R32G32B32A32_FLOAT 2, 16 bytes
///   B10G11R11  VK_FORMAT_B10G11R11_UFLOAT_PACK32 122, DXGI_FORMAT_R11G11B10_FLOAT 26, 4 bytes: R bits 0-10,
///              G 11-21, B 22-31 (unsigned 5-bit-exponent floats with 6/6/5 mantissa bits, max 65024)
///   E5B9G9R9   VK_FORMAT_E5B9G9R9_UFLOAT_PACK32 123, DXGI_FORMAT_R9G9B9E5_SHAREDEXP 67, 4 bytes: 9-bit
///              mantissas R 0-8, G 9-17, B 18-26, shared exponent 27-31 (bias 15, max 65408)
/// Packed formats clamp negative and non-finite values to 0 and large ones to the format's maximum; Rgba16f clamps
/// to +/-65504. The writers return what they clamped (clamp_report.h): only Rgba32f holds a sun.
///
/// KTX2 files written here: no supercompression, levels in the level index from level 0 (largest) while the
/// level data lie in the file smallest first, each level's byte offset aligned to lcm(texel size, 4); within a
/// level the faces +X, -X, +Y, -Y, +Z, -Z (faceCount 6) follow each other, rows top to bottom. A cube's face images
/// are the rows of a vertical-strip image with the GL face basis (cubemap.h), which is KTX's and Vulkan's face
/// table. A Basic data format descriptor (RGBSDA colour model, BT.709 primaries, linear transfer) describes the
/// samples as the KTX-Software library does. Key/value data: KTXwriter = "envkit" and the caller's pairs, sorted by
/// key as the specification requires (complete cubes only, so no KTXcubemapIncomplete).
#include <envkit/core/clamp_report.h>
#include <envkit/core/image.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace envkit {

enum class GpuFormat { Rgba16f, Rgba32f, B10G11R11, E5B9G9R9 };
/// "rgba16f", "rgba32f", "rg11b10f" (also "b10g11r11"), "rgb9e5" (also "e5b9g9r9").
std::string gpu_format_name(GpuFormat format);
GpuFormat parse_gpu_format(const std::string& name);
int gpu_format_bytes(GpuFormat format);
std::uint32_t vk_format(GpuFormat format);
std::uint32_t dxgi_format(GpuFormat format);

/// Packs the first 3 (or 4, alpha defaulting to 1) channels of every texel of `image`, row by row.
std::vector<std::uint8_t> pack_texels(const Image& image, GpuFormat format);
/// The colour values of `image` that pack_texels stores clamped in `format` (none for Rgba32f).
ClampReport count_clamped(const Image& image, GpuFormat format);
/// Inverse of the 32-bit packed encodings (for tests and readers): RGB of one texel.
void unpack_b10g11r11(std::uint32_t bits, float rgb[3]);
void unpack_e5b9g9r9(std::uint32_t bits, float rgb[3]);
std::uint32_t pack_b10g11r11(const float rgb[3]);
std::uint32_t pack_e5b9g9r9(const float rgb[3]);

struct Ktx2Options {
  GpuFormat format = GpuFormat::Rgba16f;
  /// 6: each level image is a vertical strip of six N x N faces (GL basis); 1: plain 2D levels.
  int faces = 6;
  std::map<std::string, std::string> key_values;
};

/// Writes levels[0] (largest) .. levels[n-1] to `path` atomically. Each level must halve the previous size
/// (rounding down, at least 1). Throws Error("<path>: ..."). Returns the values the format clamped, over all levels.
ClampReport write_ktx2(const std::string& path, const std::vector<const Image*>& levels, const Ktx2Options& options);

/// What the header of a KTX2 or DDS file (as written here) says, for envinfo.
struct GpuTextureInfo {
  std::string container;  ///< "ktx2" or "dds"
  std::string format;     ///< gpu_format_name, or "vk <n>" / "dxgi <n>" for formats envkit does not write
  int width = 0, height = 0, faces = 1, levels = 1;
  std::map<std::string, std::string> key_values;  ///< KTX2 key/value data (values without the trailing NUL)
};
/// True when the file starts with the KTX2 identifier or "DDS ".
bool is_gpu_texture(const std::string& path);
/// Reads the header (and KTX2 key/value data). Throws Error("<path>: ...") for short or malformed files.
GpuTextureInfo read_gpu_texture_info(const std::string& path);

/// The texels of a KTX2 file of the kind write_ktx2 writes, decoded to float.
struct Ktx2Texels {
  GpuFormat format = GpuFormat::Rgba16f;
  int faces = 1;  ///< 6 for a cube, 1 for a 2D map
  /// levels[m]: N_m x (faces N_m) with 4 channels R, G, B, A (alpha 1 for the packed formats); a cube level is the
  /// vertical strip of its faces in the file's face order (+X, -X, +Y, -Y, +Z, -Z: the GL basis of cubemap.h).
  std::vector<Image> levels;
  std::map<std::string, std::string> key_values;
};
/// Reads every level of an uncompressed KTX2 file in one of the GpuFormat formats (no supercompression, square
/// levels of halving size). Throws Error("<path>: ...") for anything else, or a truncated or inconsistent file.
Ktx2Texels read_ktx2(const std::string& path);

}  // namespace envkit
