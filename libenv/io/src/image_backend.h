#pragma once
// What image_io.cpp needs from a format library, in envkit's own terms, so that OpenImageIO can live in a module loaded
// on first need (libenvkit_oiio.so, libenv/io/modules/image_io_oiio.cpp): a run that only touches OpenEXR, Radiance,
// PFM or PNG files never loads OIIO and its ~250 shared libraries. PNG has a second implementation, on libpng in
// libenv.
//
// The module and libenv are built together by the same compiler, so C++ types cross the boundary; the entry point's
// name carries the interface version (kOiioEntryPoint), and a module of another version is not found.
#include <array>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace envkit::detail {

/// A file's header as image_io.cpp's checks and colour decisions see it (OIIO's names where they apply).
struct FileSpec {
  std::string format;      ///< "openexr", "png", "tiff", ...
  std::string pixel_type;  ///< "half", "float", "uint8", "uint16", ...
  bool floating_point = false;
  int bits_per_sample = 0;  ///< oiio:BitsPerSample, 0 when not given
  int format_bytes = 4;     ///< bytes per channel value
  bool deep = false;
  bool subsampled = false;  ///< some channel has fewer samples than pixels (OpenEXR chroma)
  /// OpenEXR luminance/chroma (Y, RY, BY[, A]), described as the R, G, B[, A] half pixels that OpenEXR's RGBA
  /// interface reconstructs from it
  bool luminance_chroma = false;
  int depth = 1;
  int width = 0, height = 0, nchannels = 0;
  int x = 0, y = 0, full_x = 0, full_y = 0, full_width = 0, full_height = 0;
  std::vector<std::string> channel_names;
  int alpha_channel = -1;           ///< as the library reports it, -1 if none
  std::string colorspace_tag;       ///< oiio:ColorSpace
  float gamma = 2.2f;               ///< oiio:Gamma
  bool has_chromaticities = false;  ///< OpenEXR chromaticities Rx Ry Gx Gy Bx By Wx Wy
  std::array<float, 8> chromaticities{};
  bool unassociated_alpha = false;              ///< oiio:UnassociatedAlpha
  std::map<std::string, std::string> metadata;  ///< scalar string/int/float attributes
};

/// An open input of the module.
class BackendInput {
 public:
  virtual ~BackendInput() = default;
  virtual const FileSpec& spec() const = 0;
  /// Reads all channels of subimage 0, MIP level 0 as interleaved float into `pixels` (width * height * nchannels
  /// floats). Returns "" or the library's message.
  virtual std::string read(float* pixels) = 0;
};

/// What a writer for a path's extension can do.
struct WriterInfo {
  std::string format;
  bool alpha = true;
};

/// Everything the module needs to write one image.
struct WriteSpec {
  int width = 0, height = 0, channels = 0;
  std::string pixel_type;  ///< "float", "half", "uint8", "uint16"
  std::vector<std::string> channel_names;
  int alpha_channel = -1;
  bool unassociated_alpha = false;
  std::vector<std::pair<std::string, std::string>> attributes;  ///< string attributes (compression, metadata)
};

class ImageBackend {
 public:
  virtual ~ImageBackend() = default;
  /// Opens `path` (keeping unassociated alpha as stored). On failure returns null and sets `error`; `unknown_format`
  /// tells that no reader recognised the file.
  virtual std::unique_ptr<BackendInput> open(const std::string& path, std::string& error, bool& unknown_format) = 0;
  /// Whether a writer exists for `path`'s extension; fills `info`.
  virtual bool writer_for(const std::string& path, WriterInfo& info) = 0;
  /// Writes `pixels` (interleaved float) to `file` and checks that it reads back. Returns "" or a message.
  virtual std::string write(const std::string& file, const WriteSpec& spec, const float* pixels) = 0;
};

/// The module's entry point: extern "C" ImageBackend* envkit_oiio_backend_v2().
inline constexpr const char* kOiioEntryPoint = "envkit_oiio_backend_v2";

/// The OIIO module, loaded on first call (dlopen). Throws Error("<path>: <why the module is unavailable>").
ImageBackend& oiio_backend(const std::string& path);

/// PNG through libpng, linked into libenv (image_io_png.cpp): what OIIO's PNG reader and writer do, without
/// loading the module.
ImageBackend& png_backend();
/// Whether the file at `path` starts with PNG's signature (false for a missing file).
bool is_png_file(const std::string& path);
/// Whether `path` ends in .png (any case): the extension picks the writer, as for the other formats.
bool is_png_path(const std::string& path);

/// The backend that reads `path` (by its first bytes) or writes it (by its extension).
inline ImageBackend& backend_for_reading(const std::string& path) {
  return is_png_file(path) ? png_backend() : oiio_backend(path);
}
inline ImageBackend& backend_for_writing(const std::string& path) {
  return is_png_path(path) ? png_backend() : oiio_backend(path);
}

}  // namespace envkit::detail
