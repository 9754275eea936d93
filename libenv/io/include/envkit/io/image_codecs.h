#pragma once
/// @file image_codecs.h
/// envkit's own codecs for the two plain HDR formats HDRI libraries ship: Radiance RGBE/XYZE (.hdr) and PFM. They work
/// on bytes in memory (read_image() reads the file, the fuzzers feed bytes directly) and decode and encode scanlines on
/// all cores (oneTBB). Every failure throws envkit::Error("<name>: <problem>") on one line, `name` being the file name
/// to report.
///
/// Radiance .hdr (the format of Greg Ward's Radiance, "#?RADIANCE" header):
///  - FORMAT=32-bit_rle_rgbe and FORMAT=32-bit_rle_xyze (no FORMAT line = RGBE); other formats are refused.
///  - EXPOSURE= and COLORCORR= lines state by how much the stored values were multiplied; decoding divides by their
///    product (several lines multiply), so the returned values are the original radiance, as Radiance's own tools do.
///    PRIMARIES= is reported (RadianceHeader::primaries), not applied.
///  - The resolution string may take any of the 8 forms (-Y H +X W is the standard; +Y H +X W stores the bottom row
///    first; -Y H -X W each row right to left; +X W -Y H etc. store columns). The decoded Image is always as displayed:
///    row 0 is the top of the picture (Radiance's +Y is up), column 0 its left edge.
///  - Scanlines may be new-style RLE, old-style RLE (repeat pixels 1,1,1,n) or flat, mixed per scanline. New-style
///    scanlines are located by one serial pass over the run headers and decoded in parallel; the pass checks every run,
///    so all errors (truncated data, scanline length mismatch, run overflow) are found before any pixel is written, and
///    the first one in file order is reported.
///  - Pixel value: mantissa * 2^(exponent - 136), as OpenImageIO, stb_image and Bruce Walter's rgbe.c decode (exponent
///    0 = black). The encoder rounds to the nearest mantissa, so a round trip errs by at most half a step: at most
///    1/255 of the largest component of the texel.
///  - XYZE data is CIE XYZ relative to Radiance's equal-energy white (X = Y = Z is white); decode_radiance returns it
///    as it is (RadianceHeader::xyze tells) and radiance_xyz_to_rec709() gives the matrix to linear Rec.709/sRGB
///    primaries, D65 white (Bradford adaptation from E to D65, so Radiance's white stays R = G = B).
///
/// PFM (Portable Float Map): "PF" (RGB) or "Pf" (grey), whitespace, width, height, scale, one whitespace byte, then
/// 32-bit floats, rows bottom to top. A negative scale means little-endian data, a positive one big-endian; its
/// magnitude is reported, not applied (OpenImageIO and most readers ignore it too).
#include <envkit/core/image.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace envkit {

/// What a Radiance header says.
struct RadianceHeader {
  int width = 0;   ///< displayed width (the X resolution)
  int height = 0;  ///< displayed height (the Y resolution)
  bool xyze = false;
  double exposure = 1.0;                     ///< product of the EXPOSURE lines (> 0)
  std::array<double, 3> colorcorr{1, 1, 1};  ///< product of the COLORCORR lines (each > 0)
  std::string primaries;                     ///< the PRIMARIES line's value, "" when absent
  std::string resolution;                    ///< the resolution string as read, e.g. "-Y 512 +X 1024"
  bool y_major = true;                       ///< scanlines are rows (else columns)
  bool x_decreasing = false;                 ///< X runs right to left in the file
  bool y_decreasing = true;                  ///< Y runs top to bottom in the file (Radiance's +Y is up)
  std::size_t data_offset = 0;               ///< first byte of pixel data
  /// Every other "KEY=value" line of the header (SOFTWARE, VIEW, envkit:parameterization, ...), in order.
  std::vector<std::pair<std::string, std::string>> variables;

  int scanline_count() const { return y_major ? height : width; }
  int scanline_length() const { return y_major ? width : height; }
};

/// Longest header envkit reads (Radiance headers hold command histories, but not megabytes of them).
inline constexpr std::size_t kRadianceMaxHeaderBytes = std::size_t(1) << 20;

/// True if `bytes` start like a Radiance file ("#?").
bool looks_like_radiance(std::span<const unsigned char> bytes);

/// Parses the header and the resolution string. Throws Error("<name>: ...") for a missing "#?" line, a header longer
/// than kRadianceMaxHeaderBytes, an unsupported FORMAT, a non-positive EXPOSURE/COLORCORR, or a bad resolution string.
/// Sizes are not limited here: the caller checks them before decoding.
RadianceHeader parse_radiance_header(std::span<const unsigned char> bytes, const std::string& name);

/// Decodes the pixels after the header into a width x height x 3 float image (channels R, G, B; or X, Y, Z for XYZE
/// data), row 0 at the top, divided by exposure and colour correction. Throws Error("<name>: cannot read pixels:
/// scanline <s>: <problem>") for corrupt data; nothing is returned then.
Image decode_radiance(std::span<const unsigned char> bytes, const RadianceHeader& header, const std::string& name);

/// Row-major 3x3 matrix taking Radiance XYZ (equal-energy white) to linear Rec.709 RGB (D65 white).
std::array<double, 9> radiance_xyz_to_rec709();

/// Encodes the first three channels of `image` (RGB, non-negative finite values) as a standard Radiance file:
/// "#?RADIANCE", FORMAT=32-bit_rle_rgbe, "-Y H +X W", new-style RLE scanlines when 8 <= width <= 32767 (flat RGBE
/// scanlines otherwise). `variables` become "KEY=value" header lines (Radiance readers ignore keys they do not know);
/// newlines in them are written as spaces.
///  - Texels: mantissas rounded to nearest (float x * 2^(8 - e) + 0.5, truncated; one more exponent when the largest
///    component rounds to 256). Negative components and NaN are written as 0; a texel whose largest component is
///    below 1e-38 as black (0, 0, 0, 0); from 2^127 on (after rounding), and +Inf, as (255, 255, 255, 255).
///    write_image() refuses images with NaN or Inf before it gets here.
///  - Runs: each channel plane is cut into runs of equal bytes of at most 127; runs of 4 or more are stored as runs,
///    the rest as literal dumps of at most 128 bytes.
///  - Rows are encoded in parallel (oneTBB), each on its own, so the bytes never depend on the number of threads.
/// The form with `sink` hands the file to it in order (header, then blocks of whole encoded rows, usually a few hundred
/// KiB each): besides the image, memory stays at 16 such blocks whatever the image size and core count.
void encode_radiance(const Image& image, const std::map<std::string, std::string>& variables,
                     const std::function<void(const unsigned char*, std::size_t)>& sink);
std::vector<unsigned char> encode_radiance(const Image& image,
                                           const std::map<std::string, std::string>& variables = {});

/// What a PFM header says.
struct PfmHeader {
  int width = 0, height = 0, channels = 0;  ///< channels: 3 ("PF") or 1 ("Pf")
  bool little_endian = true;
  double scale = 1.0;  ///< |scale| as written
  std::size_t data_offset = 0;
  std::size_t data_bytes() const {
    return std::size_t(width) * std::size_t(height) * std::size_t(channels) * sizeof(float);
  }
};

/// True if `bytes` start with "PF" or "Pf" followed by whitespace.
bool looks_like_pfm(std::span<const unsigned char> bytes);

/// Parses a PFM header (the first bytes of the file suffice). Throws Error("<name>: ...") when malformed. Width and
/// height are not limited here beyond fitting in an int.
PfmHeader parse_pfm_header(std::span<const unsigned char> bytes, const std::string& name);

/// Turns `data` (PfmHeader::data_bytes() bytes as stored in the file) into the image, in place where possible: byte
/// order fixed and rows flipped so that row 0 is the top. Channel names "R", "G", "B" or "Y".
Image decode_pfm(FloatBuffer&& data, const PfmHeader& header);

/// The PFM file of a 1- or 3-channel image: little-endian, scale -1.0, rows bottom to top.
std::vector<unsigned char> encode_pfm_header(const Image& image);

}  // namespace envkit
