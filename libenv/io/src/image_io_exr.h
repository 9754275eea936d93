#pragma once
// OpenEXR headers read with OpenEXR itself, in the terms of image_backend.h, so that EXR files never need OIIO.
#include <optional>
#include <string>

#include "image_backend.h"

namespace envkit::detail {

/// The header of part 0 of `path` as OIIO would describe it (channels grouped by layer, "diffuse" of "diffuse.R",
/// and within a layer R, G, B, A first, then the others alphabetically; "compression", "PixelAspectRatio",
/// "ImageDescription" for "comments", ... as metadata; oiio:ColorSpace "Linear" unless the file says otherwise; a
/// luminance/chroma file as the R, G, B[, A] half pixels OpenEXR's RGBA interface reconstructs, where OIIO refuses it).
/// std::nullopt when the file is not an OpenEXR file or OpenEXR cannot read its header (the OIIO module then reports
/// the problem in its words). Throws Error naming the path when a header attribute claims more bytes than the file
/// holds (OpenEXR would allocate that much first).
std::optional<FileSpec> read_exr_spec(const std::string& path);

/// True when read_exr_spec's file can be read by OpenEXR into envkit's interleaved float buffer: not deep, one sample
/// per pixel in every channel (no subsampled chroma).
bool exr_layout_supported(const FileSpec& spec);

/// Reads a file whose spec is luminance_chroma through OpenEXR's RGBA interface (which reconstructs the chroma and
/// applies the file's chromaticities) into `pixels`: width x height texels of R, G, B[, A] floats, rows top-down.
/// Throws OpenEXR's exceptions.
void read_exr_luminance_chroma(const std::string& path, const FileSpec& spec, float* pixels);

}  // namespace envkit::detail
