#pragma once
// Reading and writing the formats envkit decodes itself (Radiance .hdr, PFM): files to and from the codecs of
// image_codecs.h. Internal to image_io.cpp.
#include <envkit/core/image.h>

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace envkit::detail {

enum class NativeFormat { None, Radiance, Pfm };

/// The format of a regular file judged by its first bytes (not its extension, which users get wrong).
NativeFormat sniff_native_format(const std::string& path);

struct NativeRead {
  Image image;             ///< RGB/Y floats as stored (XYZ for XYZE files), row 0 at the top
  std::string format;      ///< "hdr" or "pfm"
  std::string pixel_type;  ///< "rgbe", "xyze" or "float"
  bool xyze = false;
  std::vector<std::string> notes;
};

/// Reads a file of a native format. `check_size(width, height, channels)` runs on the header, before any pixel memory
/// is allocated, and throws to refuse.
NativeRead read_native(const std::string& path, NativeFormat format,
                       const std::function<void(int, int, int)>& check_size);

/// Writes `data` (3 channels for .hdr; 1 or 3 for .pfm) to `file`; errors name `path`.
void write_radiance_file(const std::string& path, const std::string& file, const Image& data,
                         const std::map<std::string, std::string>& variables);
void write_pfm_file(const std::string& path, const std::string& file, const Image& data);

}  // namespace envkit::detail
