#pragma once
/// @file exr_cube_mips.h
/// A cube map mip chain in one OpenEXR file, the way OpenEXR itself stores cube environments (ImfEnvmap.h,
/// exrenvmap): a tiled file with level mode MIPMAP_LEVELS and rounding ROUND_DOWN whose level 0 is an N x 6N
/// vertical strip, the envmap attribute ENVMAP_CUBE, faces top to bottom in OpenEXR's order +X, -X, +Y, -Y, +Z, -Z
/// with OpenEXR's face orientation (CubeBasis::Envkit in cubemap.h) and corner sampling (TexelGrid::Corner: edge
/// texels centred on the cube's edges, as Imf::CubeMap::direction computes).
///
/// OpenEXR defines the face size of level l as min(W_l, H_l / 6) with W_l = max(1, N >> l) and
/// H_l = max(1, 6N >> l) (Imf::CubeMap::sizeOfFace): that is N >> l while N >> l >= 1, and rows past the six faces
/// (H_l - 6 (N >> l), at most 5, only for sizes that are not powers of two) are padding, written as 0. A MIPMAP_LEVELS
/// file holds floor(log2(6N)) + 1 levels, down to a 1 x 1 image, which is more than a cube's own chain: level l
/// past the given levels is the box average of level l - 1 face by face (2 x 2 texels, 3 wide where an odd face halves)
/// while faces remain, and then (face size 0, images of 1 x 3 down to 1 x 1) the mean of the last level with faces.
/// envkit:ibl_levels tells readers how many levels are the caller's.
#include <envkit/core/clamp_report.h>
#include <envkit/core/image.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace envkit {

struct ExrCubeMipsOptions {
  bool half = false;  ///< HALF instead of FLOAT channels (values beyond +/-65504 stored as +/-65504)
  int tile = 64;      ///< tile width and height in pixels
  /// String attributes written into the header (envkit:* keys and the like); "envmap" and the standard
  /// attributes are reserved. envkit:ibl_levels is added.
  std::map<std::string, std::string> attributes;
};

/// Number of levels of an OpenEXR MIPMAP_LEVELS, ROUND_DOWN file of N x 6N (floor(log2(6N)) + 1).
int exr_cube_mip_levels(int face_size);

/// Writes `levels` (levels[m]: vertical strip of face size max(1, N >> m) in the layout above, same channels in
/// every level, at most 4 channels named as in the image; at least one level, at most the cube's full chain
/// floor(log2 N) + 1) to `path`. Throws Error("<path>: ...") for inconsistent levels or a failed write (the caller
/// writes to a temp path: atomic_file.h). Returns the values half clamped, over every level written.
ClampReport write_exr_cube_mips(const std::string& path, const std::vector<const Image*>& levels,
                                const ExrCubeMipsOptions& options = {});

/// The resolution levels of part 0 of an OpenEXR file (for envinfo; envkit's readers read level 0).
struct ExrLevels {
  std::string mode = "single";             ///< "single" (scanline or ONE_LEVEL), "mipmap" or "ripmap"
  std::string rounding;                    ///< "down" or "up" for tiled multi-level files
  std::vector<std::pair<int, int>> sizes;  ///< width, height of each level (ripmaps: the diagonal levels)
};
/// Reads the header (and, for tiled files, the level sizes); std::nullopt when OpenEXR cannot read the file.
std::optional<ExrLevels> read_exr_levels(const std::string& path);

}  // namespace envkit
