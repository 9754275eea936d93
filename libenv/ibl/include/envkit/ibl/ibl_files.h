#pragma once
/// @file ibl_files.h
/// The files envprefilter writes for real-time IBL, shared with the Python module so that both write the same
/// bytes: a GGX chain (prefilter.h) or an irradiance map in KTX 2.0 (ktx2.h), DDS (dds.h) or OpenEXR, the
/// container chosen by the extension, with the metadata that names the roughness mapping, the roughness and alpha
/// of every level, the lobe, the parameterization and the GL convention of the faces.
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/ktx2.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/maps/parameterization.h>

#include <map>
#include <string>
#include <vector>

namespace envkit {

/// One output file: its target path, the levels it holds and its metadata.
struct IblFile {
  std::string path;
  std::vector<const Image*> levels;  ///< largest first; point into the chain or map they were made from
  std::map<std::string, std::string> metadata;
  /// Every level in one tiled, mip-mapped OpenEXR cube (exr_cube_mips.h) rather than one image per file.
  bool exr_cube_mips = false;
};

/// Throws Error("<path>: expected a .ktx2, .dds or .exr file") for another extension.
void check_ibl_output(const std::string& path);

/// True for a chain written as one mip-mapped OpenEXR cube: an .exr name without '%'.
bool is_exr_cube_mips_path(const std::string& path);

/// Sets the faces a chain written to `path` must be prefiltered into: OpenEXR's face basis and corner grid for one
/// mip-mapped OpenEXR cube (its own layout, so the finished chain is never resampled), the GL table otherwise.
void set_ibl_cube_faces(const std::string& path, PrefilterOptions& options);

/// The files of `chain` (levels of `kind`, read from a file named `source`) written to `pattern`: one .ktx2 or
/// .dds holding every level; one .exr per level with '%' replaced by the level number (0, 1, ...), which also
/// records envkit:ibl_level and envkit:layout; or, for an .exr name without '%', one mip-mapped OpenEXR cube (the
/// chain prefiltered with set_ibl_cube_faces; Error for an octahedral chain, which that file cannot hold).
std::vector<IblFile> ggx_chain_files(const std::string& pattern, const PrefilteredChain& chain, Kind kind,
                                     const std::string& source);

/// The file of an irradiance map (irradiance_map's output, of `kind`) written to `path`.
IblFile irradiance_file(const std::string& path, const EnvMap& irradiance, Kind kind);

/// Writes `file` into `write_path`, atomically as every envkit writer does: file.path itself, or a path where the
/// caller stages it (envprefilter: a temp path it renames at the end). The container follows file.path's extension.
/// cube: every level is a vertical strip of six faces (GL basis). `format` is the texel format of KTX2 and DDS files
/// (OpenEXR stores floats). Returns the values that format clamped (clamp_report.h), for the caller's warning.
ClampReport write_ibl_file(const std::string& write_path, const IblFile& file, bool cube, GpuFormat format);

}  // namespace envkit
