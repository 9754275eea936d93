#pragma once
/// @file image_io.h
/// Reading and writing images, with envkit's checks (OCIO through color.h).
///
/// Every failure throws envkit::Error with one line "<path>: <problem>".
///
/// Who decodes what (docs/image-io.md): the format is taken from the file's first bytes. OpenEXR files are read
/// by OpenEXR, Radiance (.hdr) and PFM files by envkit's own codecs (image_codecs.h: every Radiance orientation,
/// XYZE converted to Rec.709, EXPOSURE/COLORCORR divided out); every other format by OpenImageIO, which lives in
/// a module (libenvkit_oiio.so) loaded on first need, so EXR/HDR/PFM-only programs never load it.
/// Inputs must be regular files (input_checks.h): FIFOs, devices and directories are refused before opening.
///
/// Reading: subimage 0, MIP level 0 of any format OIIO reads; 1 to 4 channels (Y, YA, RGB, RGBA); the
/// result is float, in the working colour space (color.h), alpha last. Pixels are decoded from the file's
/// colour space:
///  - ReadOptions::colorspace when given;
///  - else OIIO's "oiio:ColorSpace" tag when it names something envkit knows ("Linear", "sRGB", "Rec709",
///    "GammaCorrected"/"Gamma<g>", or an OCIO colour-space name), except that 8-bit data is never taken to be
///    linear (decoded as sRGB, with a note in the report) and float data is never taken to be
///    transfer-encoded (OIIO tags every PNM file "Rec709", PFM included). 8/16-bit PPM/PGM files therefore
///    decode with the Rec.709 OETF, as the Netpbm format specifies;
///  - else OpenEXR chromaticities matching ACES AP0/AP1, Rec.709, P3-D65 or Rec.2020 primaries;
///  - else: float/half data (EXR, HDR, PFM, float TIFF) is the working space, integer data is sRGB
///    (OpenEXR integer (UINT) channels are data: "raw").
///
/// Alpha: colour is associated (premultiplied by alpha), as in OpenEXR and OIIO. Files that store
/// unassociated alpha (PNG, TIFF with unassociated extra samples) are premultiplied after decoding, in linear
/// light; integer outputs are un-premultiplied in linear light before encoding (a texel with alpha 0 then
/// has colour 0).
///
/// Size limits (checked on the header, before pixel memory is allocated): width, height >= 1,
/// each side <= ReadOptions::max_side (default 2^18 = 262144), width * height <= ReadOptions::max_texels
/// (default 2^30, i.e. 32768 x 32768, 12 GiB of float RGB), and the float buffer must fit in the memory
/// available (input_checks.h: "image too large: WxH (C channels, float) needs X GiB of memory, Y GiB
/// available"). More than 4 channels is refused.
///
/// Writing: the format follows the extension. Files are written atomically (atomic_file.h).
///  - .exr: written with the OpenEXR library: float (default) or half, "zip" compression by default,
///    Rec.709/D65 chromaticities when the working space is lin_rec709. WriteOptions::envmap_attribute writes
///    OpenEXR's typed "envmap" attribute (Imf::EnvmapAttribute) that exrenvmap and renderers read. (OIIO 2.4
///    could write it through its "textureformat" hint, but it also stores a "textureformat" string attribute
///    that exrenvmap copies into its outputs, where it contradicts the typed attribute for OIIO readers.)
///    Reading takes "envmap" from the typed attribute too. The metadata key "oiio:sampleborder" is written as an
///    integer attribute, the type OIIO's texture system reads (oiio_env_tags.h); every other key as a string.
///  - .hdr (RGBE, written by envkit: "-Y H +X W", new-style RLE, rows encoded in parallel; envkit:* metadata as
///    header lines): always RGB; Y is replicated, alpha dropped, negatives written as 0. Precision: within
///    1/255 of the texel's largest component.
///  - .pfm: float, Y or RGB (alpha dropped), little-endian, bottom-to-top rows per the PFM convention.
///    Written by envkit (image_codecs.h); OIIO 2.4 cannot write PFM.
///  - .tif/.tiff: float by default (linear), or uint8/uint16 (then sRGB-encoded like PNG).
///  - .png, .jpg and every other integer-only format: colour converted from the working space to
///    WriteOptions::encode_colorspace (default "srgb"; "rec709" for Netpbm) through OCIO, clamped to [0, 1],
///    quantised by OIIO (round to nearest). Never linear values. JPEG and other formats without alpha drop
///    alpha.
#include <envkit/core/clamp_report.h>
#include <envkit/core/image.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace envkit {

/// What to do with NaN and +/-Inf values found in a file.
enum class NonFinitePolicy {
  Error,  ///< throw Error("<path>: N non-finite values (a NaN, b Inf); pass --fix-nonfinite zero|clamp")
  Zero,   ///< NaN, +Inf, -Inf -> 0
  Clamp,  ///< NaN -> 0, +Inf -> the largest finite value of that channel in the image (0 if none), -Inf -> 0
};

/// NaN, +Inf and -Inf among `values`, counted on all cores.
struct NonFiniteCounts {
  std::size_t nan = 0, posinf = 0, neginf = 0;
  std::size_t total() const { return nan + posinf + neginf; }
  NonFiniteCounts operator+(const NonFiniteCounts& o) const {
    return {nan + o.nan, posinf + o.posinf, neginf + o.neginf};
  }
};
NonFiniteCounts count_nonfinite(std::span<const float> values);

/// "error", "zero", "clamp" (for command lines). Throws Error on other names.
NonFinitePolicy parse_nonfinite_policy(const std::string& name);
const char* nonfinite_policy_name(NonFinitePolicy policy);

struct ReadOptions {
  /// Colour space of the file's pixels (any OCIO name/alias/role); empty = decide from the file.
  std::string colorspace;
  NonFinitePolicy nonfinite = NonFinitePolicy::Error;
  /// Refuse images with more texels than this (checked before allocating).
  std::int64_t max_texels = std::int64_t(1) << 30;
  /// Refuse images with a side longer than this.
  int max_side = 1 << 18;
};

/// What read_image found and did.
struct ReadReport {
  std::string format;             ///< "openexr", "hdr", "pfm" (envkit's codecs), or OIIO's name: "png", "tiff", ...
  std::string pixel_type;         ///< the file's pixel type: "half", "float", "uint8", "uint16", ...
  std::string file_colorspace;    ///< colour space the pixels were decoded from ("srgb", "gamma 2.2", ...)
  std::string colorspace_reason;  ///< why: "option", "file tag oiio:ColorSpace=sRGB", "default for integer data"
  bool converted = false;         ///< true if a colour conversion to the working space was applied
  std::string working_space;      ///< colour space of the returned pixels
  // Counts over all channels of the file's values (before any colour conversion).
  std::size_t nan_count = 0;
  std::size_t posinf_count = 0;
  std::size_t neginf_count = 0;
  /// Finite values < 0 in the returned pixels (after conversion: wide-gamut sources can produce them).
  std::size_t negative_count = 0;
  NonFinitePolicy policy = NonFinitePolicy::Error;
  /// Values replaced by the policy (== nonfinite_count() unless the policy is Error, which throws).
  std::size_t replaced_count = 0;
  std::vector<std::string> notes;  ///< warnings for the user (e.g. "8-bit data tagged Linear: decoded as sRGB")

  std::size_t nonfinite_count() const { return nan_count + posinf_count + neginf_count; }
  /// One line, e.g. "openexr half, colour space lin_rec709 (default for float data), 0 non-finite, 3 negative".
  std::string summary() const;
};

/// Reads subimage 0, MIP level 0 of `path` into a float image in the working colour space.
/// Image::metadata receives every scalar string/int/float attribute of the file (OIIO names, e.g.
/// "compression", "oiio:ColorSpace", "DateTime") plus "envmap" = "latlong" | "cube" when an OpenEXR file
/// carries the envmap attribute. Channel names come from the file; alpha is detected from OIIO's alpha
/// channel or a channel named "A"/"Alpha" (else, for 2 and 4 channels, the last channel) and moved last.
/// If `report` is non-null it is filled in.
Image read_image(const std::string& path, const ReadOptions& options = {}, ReadReport* report = nullptr);

/// Pixel type of the written file.
enum class PixelType {
  Auto,  ///< float for EXR/TIFF/PFM (HDR is RGBE), uint8 for integer-only formats
  Half,  ///< EXR only; values beyond +/-65504 are stored as +/-65504 (not Inf) and reported
  Float,
  UInt8,   ///< sRGB-encoded (see encode_colorspace)
  UInt16,  ///< sRGB-encoded (PNG, TIFF)
};

/// Whether `name` (case-insensitive, optionally with a level as in "dwaa:45") names an OpenEXR compression.
bool is_exr_compression(const std::string& name);
/// The OpenEXR compression names, comma separated, for messages.
const char* exr_compression_list();

struct WriteOptions {
  PixelType pixel_type = PixelType::Auto;
  /// OIIO compression name ("zip", "piz", "dwaa:45", "none", "jpeg:95", ...); empty = format default
  /// ("zip" for EXR and TIFF, quality 95 for JPEG).
  std::string compression;
  /// "" (none), "latlong" or "cube": the OpenEXR envmap attribute. EXR only; "cube" needs height == 6 * width.
  std::string envmap_attribute;
  /// Written as string attributes, e.g. {"envkit:parameterization", "latlong"}. Overrides Image::metadata.
  std::map<std::string, std::string> metadata;
  /// Colour space integer outputs are encoded to (the image is in the working space). Empty = "srgb",
  /// except Netpbm files (.ppm/.pgm): "rec709", the transfer that format specifies.
  std::string encode_colorspace;
};

/// Writes `image` (working colour space) to `path` atomically. Image::metadata entries are carried over
/// when their key starts with "envkit:" or is one of the descriptive keys "ImageDescription", "Copyright",
/// "Artist", "DateTime", "owner", "comments", "capDate" (structural keys of the source file, like
/// "compression" or "oiio:ColorSpace", would be wrong for the new file); WriteOptions::metadata is written
/// as given. The "envmap" metadata key is never written: use WriteOptions::envmap_attribute.
/// Throws Error("<path>: ...") for empty images, non-finite pixels, unknown formats, unwritable
/// directories ("<path>: cannot write: ...") and writer failures; nothing appears at `path` then.
/// Returns the values the file could not hold (clamp_report.h): beyond +/-65504 in a half OpenEXR file, negative
/// colour in a Radiance file (stored as 0); nothing for other outputs (integer formats are display-referred by
/// design).
ClampReport write_image(const std::string& path, const Image& image, const WriteOptions& options = {});

}  // namespace envkit
