#pragma once
/// @file dds.h
/// A DDS writer for IBL outputs: "DDS " + DDS_HEADER (124 bytes) + DDS_HEADER_DXT10 (20 bytes), uncompressed
/// DXGI formats (ktx2.h: R16G16B16A16_FLOAT 10, R32G32B32A32_FLOAT 2, R11G11B10_FLOAT 26, R9G9B9E5_SHAREDEXP 67).
/// Cubes set DDSCAPS2_CUBEMAP with all six faces and DDS_RESOURCE_MISC_TEXTURECUBE (0x4) with arraySize 1; the data
/// are face-major (face 0 level 0, level 1, ..., then face 1), faces +X, -X, +Y, -Y, +Z, -Z. Direct3D's cube face
/// table (u right, v down) is the same as GL's, so the faces are the vertical-strip rows of a GL-basis cube
/// (cubemap.h) exactly as in KTX2: a lookup vector sees the same texel in both files.
#include <envkit/ibl/ktx2.h>

namespace envkit {

struct DdsOptions {
  GpuFormat format = GpuFormat::Rgba16f;
  int faces = 6;  ///< 6: levels are N x 6N vertical strips (GL basis); 1: 2D levels
};

/// Writes levels[0] (largest) .. levels[n-1] to `path` atomically. Throws Error("<path>: ..."). Returns the values the
/// format clamped, over all levels.
ClampReport write_dds(const std::string& path, const std::vector<const Image*>& levels, const DdsOptions& options);

}  // namespace envkit
