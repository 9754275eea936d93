// PNG through libpng itself, behind image_backend.h's interface. PNG is the format envkit writes most often (LUTs,
// previews, LDR probes), and through OpenImageIO every such file cost the module's load: about 0.45 s of wall time
// and 0.5 s of CPU for ~250 shared libraries, against a few milliseconds for libpng. The FileSpec and the pixels are
// those OpenImageIO's PNG reader gives (test_image_io_png compares the two on every kind of PNG), so image_io.cpp
// decides colour and alpha the same way whichever backend read the file.
//
// libpng reports errors with longjmp: every function that calls into libpng after a setjmp keeps only trivially
// destructible locals alive across those calls, and the C++ objects (strings, vectors) live in the caller.
#include <png.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "image_backend.h"

namespace envkit::detail {
namespace {

/// libpng's error message of the failing call, kept by the error callback before it longjmps.
struct ErrorSink {
  char message[256] = "";
  int error_number = 0;  // errno when the error was reported: why libpng's "Write Error" happened
};

[[noreturn]] void on_error(png_structp png, png_const_charp message) {
  const int error_number = errno;
  if (auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png))) {
    std::snprintf(sink->message, sizeof sink->message, "%s", message ? message : "libpng error");
    sink->error_number = error_number;
  }
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}  // warnings (e.g. a bad optional chunk) do not stop reading

/// A FILE* that closes itself.
struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

/// The message of a failed read: libpng's own says "Read Error" for a file that ends early.
std::string read_failure(const ErrorSink& sink, std::FILE* f) {
  if (std::feof(f)) return "the file ends early (truncated PNG)";
  return sink.message[0] ? sink.message : "unsupported PNG layout";
}

/// PNG's 8-byte signature.
bool has_png_signature(std::FILE* f) {
  png_byte header[8];
  return std::fread(header, 1, 8, f) == 8 && png_sig_cmp(header, 0, 8) == 0;
}

// ---- reading --------------------------------------------------------------------------------------------------

/// Walks the chunk list after the signature and checks that no chunk claims more bytes than the file holds after
/// its header: libpng allocates what a text chunk's length says before reading it (1.8 GB for a 500-byte file in
/// fuzzing), whatever png_set_chunk_malloc_max says. Returns "" or the problem; leaves `f` just after the signature.
std::string check_chunk_lengths(std::FILE* f) {
  if (std::fseek(f, 0, SEEK_END) != 0) return "cannot seek";
  const long size = std::ftell(f);
  long at = 8;
  std::string problem;
  while (at + 8 <= size) {
    unsigned char head[8];
    if (std::fseek(f, at, SEEK_SET) != 0 || std::fread(head, 1, 8, f) != 8) break;
    const std::uint32_t length = (std::uint32_t(head[0]) << 24) | (std::uint32_t(head[1]) << 16) |
                                 (std::uint32_t(head[2]) << 8) | std::uint32_t(head[3]);
    const long left = size - at - 12;  // after the length, type and CRC
    if (length > 0x7fffffffu || long(length) > left) {
      char type[5] = {};
      for (int i = 0; i < 4; ++i) type[i] = std::isprint(head[4 + i]) ? char(head[4 + i]) : '?';
      problem = "chunk '" + std::string(type) + "' at byte " + std::to_string(at) + " claims " +
                std::to_string(length) + " bytes, more than the file holds (truncated or corrupt PNG)";
      break;
    }
    if (std::memcmp(head + 4, "IEND", 4) == 0) break;
    at += 12 + long(length);
  }
  std::fseek(f, 8, SEEK_SET);
  return problem;
}

/// What read_header() learns, in plain fields (set under setjmp).
struct Header {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, channels = 0;
  int has_srgb = 0, has_gamma = 0;
  double file_gamma = 0.0;  // the gAMA chunk's value (the encoding exponent, e.g. 0.45455)
  png_int_32 x_offset = 0, y_offset = 0;
  int has_time = 0;
  png_time time{};
  png_textp text = nullptr;
  int text_count = 0;
};

/// Reads the chunks before the pixels and sets the transforms OIIO's reader sets: palette -> RGB, gray below 8 bits
/// -> 8 bits, tRNS -> alpha, 16-bit samples in native byte order. Returns false with sink.message on error.
bool read_header(png_structp png, png_infop info, std::FILE* f, Header& h) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  png_set_sig_bytes(png, 8);
  // A PNG that claims more than this is refused by libpng before any pixel memory exists; image_io.cpp's limits
  // (ReadOptions) then apply to the dimensions as for every format.
  png_set_user_limits(png, 1u << 20, 1u << 20);
  // Bounds on what hostile ancillary chunks may cost: their number, and what compressed text or an ICC profile may
  // expand to (16 MiB holds any real one). The declared lengths themselves are checked by check_chunk_lengths():
  // this libpng allocates a text chunk's declared length whatever the limit below says.
  png_set_chunk_malloc_max(png, png_alloc_size_t(16) << 20);
  png_set_chunk_cache_max(png, 1000);
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, nullptr, 0);  // skipped, never buffered
  png_read_info(png, info);
  png_set_expand(png);
  png_set_swap(png);  // PNG stores 16-bit samples big-endian (a no-op for 8-bit data)
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  h.width = png_get_image_width(png, info);
  h.height = png_get_image_height(png, info);
  h.bit_depth = png_get_bit_depth(png, info);
  h.channels = png_get_channels(png, info);
  int intent = 0;
  h.has_srgb = png_get_sRGB(png, info, &intent) != 0;
  h.has_gamma = png_get_gAMA(png, info, &h.file_gamma) != 0;
  h.x_offset = png_get_x_offset_pixels(png, info);
  h.y_offset = png_get_y_offset_pixels(png, info);
  png_timep time = nullptr;
  if (png_get_tIME(png, info, &time) && time) {
    h.has_time = 1;
    h.time = *time;
  }
  h.text_count = png_get_text(png, info, &h.text, nullptr);
  return true;
}

/// Decodes all rows (interlaced or not) into rows[]. Returns false with sink.message on error.
bool read_rows(png_structp png, png_infop info, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, info);
  return true;
}

FileSpec spec_of(const Header& h) {
  FileSpec f;
  f.format = "png";
  f.pixel_type = h.bit_depth == 16 ? "uint16" : "uint8";
  f.floating_point = false;
  f.format_bytes = h.bit_depth == 16 ? 2 : 1;
  f.width = f.full_width = static_cast<int>(h.width);
  f.height = f.full_height = static_cast<int>(h.height);
  f.nchannels = h.channels;
  f.x = h.x_offset;
  f.y = h.y_offset;
  // OIIO's names: R G B A, gray as Y and gray + alpha as Y A.
  static const char* const rgba[] = {"R", "G", "B", "A"};
  if (h.channels == 1) {
    f.channel_names = {"Y"};
  } else if (h.channels == 2) {
    f.channel_names = {"Y", "A"};
  } else {
    for (int c = 0; c < h.channels; ++c) f.channel_names.emplace_back(rgba[c]);
  }
  f.alpha_channel = h.channels == 2 ? 1 : h.channels == 4 ? 3 : -1;
  f.unassociated_alpha = true;  // PNG's alpha is straight; image_io.cpp associates it
  // Tags as OIIO 2.4 sets them: sRGB unless a gAMA chunk (without an sRGB chunk) says otherwise.
  f.colorspace_tag = "sRGB";
  // The decoding exponent is rounded to hundredths (gAMA stores 1/2.2 as 0.45455) and named like "Gamma2.2".
  if (!h.has_srgb && h.has_gamma && h.file_gamma > 0.0) {
    f.gamma = std::round(100.0f / static_cast<float>(h.file_gamma)) / 100.0f;
    char tag[32];
    std::snprintf(tag, sizeof tag, "Gamma%.2g", double(f.gamma));
    f.colorspace_tag = f.gamma == 1.0f ? "linear" : tag;
  }
  if (h.has_time) {
    char date[32];
    std::snprintf(date, sizeof date, "%4d:%02d:%02d %02d:%02d:%02d", h.time.year, h.time.month, h.time.day, h.time.hour,
                  h.time.minute, h.time.second);
    f.metadata["DateTime"] = date;
  }
  for (int i = 0; i < h.text_count; ++i) {
    const png_text& t = h.text[i];
    if (!t.key || !t.text) continue;
    std::string key = t.key;
    if (key == "Description")
      key = "ImageDescription";
    else if (key == "Author")
      key = "Artist";
    else if (key == "Title")
      key = "DocumentName";
    f.metadata[key] = std::string(t.text, t.text_length ? t.text_length : std::strlen(t.text));
  }
  return f;
}

class PngInput final : public BackendInput {
 public:
  PngInput(File file, png_structp png, png_infop info, const Header& header, std::unique_ptr<ErrorSink> sink)
      : file_(std::move(file)), png_(png), info_(info), sink_(std::move(sink)), spec_(spec_of(header)) {}
  ~PngInput() override { png_destroy_read_struct(&png_, &info_, nullptr); }
  PngInput(const PngInput&) = delete;
  PngInput& operator=(const PngInput&) = delete;

  const FileSpec& spec() const override { return spec_; }

  std::string read(float* pixels) override {
    const std::size_t w = std::size_t(spec_.width), h = std::size_t(spec_.height);
    const std::size_t samples_per_row = w * std::size_t(spec_.nchannels);
    const bool wide = spec_.format_bytes == 2;
    std::vector<png_byte> bytes(samples_per_row * h * (wide ? 2 : 1));
    std::vector<png_bytep> rows(h);
    for (std::size_t y = 0; y < h; ++y) rows[y] = bytes.data() + y * samples_per_row * (wide ? 2 : 1);
    if (!read_rows(png_, info_, rows.data())) return read_failure(*sink_, file_.get());
    // OIIO's integer -> float conversion: v times the float reciprocal of 255 or 65535 (not a division: the
    // product can be an ulp above v / 255, and the pixels must be OIIO's).
    const std::size_t n = samples_per_row * h;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 16),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        if (wide) {
                          const auto* v = reinterpret_cast<const std::uint16_t*>(bytes.data());
                          for (std::size_t i = r.begin(); i < r.end(); ++i) pixels[i] = float(v[i]) * (1.0f / 65535.0f);
                        } else {
                          for (std::size_t i = r.begin(); i < r.end(); ++i)
                            pixels[i] = float(bytes[i]) * (1.0f / 255.0f);
                        }
                      });
    return "";
  }

 private:
  File file_;
  png_structp png_;
  png_infop info_;
  std::unique_ptr<ErrorSink> sink_;  // the read struct's error pointer: on the heap, so moving it keeps the address
  FileSpec spec_;
};

// ---- writing --------------------------------------------------------------------------------------------------

/// Text chunks and the other header data of a write, prepared outside libpng's setjmp scope.
struct Chunks {
  std::vector<std::pair<std::string, std::string>> text;  // PNG keyword -> value
  bool srgb = false;
  int level = -1;  // zlib level, -1: libpng's default
  bool has_time = false;
  png_time time{};
};

/// PNG keywords: 1-79 printable Latin-1 characters without leading, trailing or double spaces.
bool valid_keyword(const std::string& k) {
  if (k.empty() || k.size() > 79 || k.front() == ' ' || k.back() == ' ' || k.find("  ") != std::string::npos)
    return false;
  return std::all_of(k.begin(), k.end(), [](char c) {
    const auto u = static_cast<unsigned char>(c);
    return (u >= 32 && u <= 126) || u >= 161;
  });
}

/// The attributes image_io.cpp passes (make_spec) as PNG chunks, with OIIO's names. Returns "" or a message.
std::string prepare_chunks(const WriteSpec& w, Chunks& out) {
  for (const auto& [key, value] : w.attributes) {
    if (key == "oiio:ColorSpace") {
      out.srgb = value == "sRGB";
    } else if (key == "compression") {
      // zip[:level] (OIIO's spelling) or none.
      if (value == "none") {
        out.level = 0;
      } else if (value == "zip") {
        out.level = -1;
      } else if (value.rfind("zip:", 0) == 0 && value.size() == 5 && value[4] >= '0' && value[4] <= '9') {
        out.level = value[4] - '0';
      } else {
        return "PNG compression is zip, zip:0..9 or none, not '" + value + "'";
      }
    } else if (key == "DateTime") {
      int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
      if (std::sscanf(value.c_str(), "%4d:%2d:%2d %2d:%2d:%2d", &year, &month, &day, &hour, &minute, &second) == 6) {
        out.has_time = true;
        out.time.year = png_uint_16(year), out.time.month = png_byte(month), out.time.day = png_byte(day);
        out.time.hour = png_byte(hour), out.time.minute = png_byte(minute), out.time.second = png_byte(second);
      }
    } else {
      const std::string k = key == "ImageDescription" ? "Description"
                            : key == "Artist"         ? "Author"
                            : key == "DocumentName"   ? "Title"
                                                      : key;
      if (valid_keyword(k)) out.text.emplace_back(k, value);
    }
  }
  return "";
}

/// Writes the header, rows and end of the file. Returns false with sink.message on error.
bool write_png(png_structp png, png_infop info, std::FILE* f, const WriteSpec& w, const Chunks& chunks, png_text* text,
               png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  static const int color_types[] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                                    PNG_COLOR_TYPE_RGB_ALPHA};
  png_set_IHDR(png, info, png_uint_32(w.width), png_uint_32(w.height), w.pixel_type == "uint16" ? 16 : 8,
               color_types[w.channels - 1], PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (chunks.level >= 0) png_set_compression_level(png, chunks.level);
  if (chunks.srgb) png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_ABSOLUTE);
  if (chunks.has_time) png_set_tIME(png, info, &chunks.time);
  if (!chunks.text.empty()) png_set_text(png, info, text, static_cast<int>(chunks.text.size()));
  png_write_info(png, info);
  png_set_swap(png);  // native 16-bit samples to PNG's big-endian
  png_write_image(png, rows);
  png_write_end(png, info);
  return true;
}

/// Float in [0, 1] (image_io.cpp has clamped it) to the file's integer, rounded to nearest as OIIO converts.
template <class T>
T quantise(float v, float scale) {
  return static_cast<T>(std::clamp(v * scale + 0.5f, 0.0f, scale));
}

class PngBackend final : public ImageBackend {
 public:
  std::unique_ptr<BackendInput> open(const std::string& path, std::string& error, bool& unknown_format) override {
    unknown_format = false;
    File f(std::fopen(path.c_str(), "rb"));
    if (!f) {
      error = std::strerror(errno);
      return nullptr;
    }
    if (!has_png_signature(f.get())) {
      unknown_format = true;
      error = "not a PNG file";
      return nullptr;
    }
    if (std::string problem = check_chunk_lengths(f.get()); !problem.empty()) {
      error = problem;
      return nullptr;
    }
    auto sink = std::make_unique<ErrorSink>();
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, sink.get(), on_error, on_warning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    if (!png || !info) {
      png_destroy_read_struct(&png, &info, nullptr);
      error = "out of memory";
      return nullptr;
    }
    Header header;
    if (!read_header(png, info, f.get(), header) || header.channels < 1 || header.channels > 4 ||
        (header.bit_depth != 8 && header.bit_depth != 16)) {
      error = read_failure(*sink, f.get());
      png_destroy_read_struct(&png, &info, nullptr);
      return nullptr;
    }
    return std::make_unique<PngInput>(std::move(f), png, info, header, std::move(sink));
  }

  bool writer_for(const std::string&, WriterInfo& info) override {
    info.format = "png";
    info.alpha = true;
    return true;
  }

  std::string write(const std::string& file, const WriteSpec& w, const float* pixels) override {
    if (w.channels < 1 || w.channels > 4) return "PNG holds 1 to 4 channels, not " + std::to_string(w.channels);
    if (w.pixel_type != "uint8" && w.pixel_type != "uint16")
      return "PNG holds 8- or 16-bit integers, not " + w.pixel_type;
    Chunks chunks;
    if (std::string e = prepare_chunks(w, chunks); !e.empty()) return e;
    std::vector<png_text> text(chunks.text.size());
    for (std::size_t i = 0; i < text.size(); ++i) {
      text[i] = png_text{};
      text[i].compression = PNG_TEXT_COMPRESSION_NONE;
      text[i].key = const_cast<char*>(chunks.text[i].first.c_str());
      text[i].text = const_cast<char*>(chunks.text[i].second.c_str());
      text[i].text_length = chunks.text[i].second.size();
    }
    // Samples in the file's width, then rows over them.
    const bool wide = w.pixel_type == "uint16";
    const std::size_t row_samples = std::size_t(w.width) * std::size_t(w.channels);
    const std::size_t n = row_samples * std::size_t(w.height);
    std::vector<png_byte> bytes(n * (wide ? 2 : 1));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 16),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        if (wide) {
                          auto* v = reinterpret_cast<std::uint16_t*>(bytes.data());
                          for (std::size_t i = r.begin(); i < r.end(); ++i)
                            v[i] = quantise<std::uint16_t>(pixels[i], 65535.0f);
                        } else {
                          for (std::size_t i = r.begin(); i < r.end(); ++i)
                            bytes[i] = quantise<png_byte>(pixels[i], 255.0f);
                        }
                      });
    std::vector<png_bytep> rows(std::size_t(w.height));
    for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = bytes.data() + y * row_samples * (wide ? 2 : 1);

    File f(std::fopen(file.c_str(), "wb"));
    if (!f) return std::strerror(errno);
    ErrorSink sink;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &sink, on_error, on_warning);
    png_infop info = png ? png_create_info_struct(png) : nullptr;
    const bool ok = png && info && write_png(png, info, f.get(), w, chunks, text.data(), rows.data());
    png_destroy_write_struct(&png, &info);
    // A failed fwrite() (a full disk) shows in the stream's error flag; its errno says why.
    if (!ok && std::ferror(f.get()) && sink.error_number != 0) return std::strerror(sink.error_number);
    if (!ok) return sink.message[0] ? sink.message : "out of memory";
    if (std::fflush(f.get()) != 0 || std::ferror(f.get())) return std::string("write error: ") + std::strerror(errno);
    return "";
  }
};

}  // namespace

bool is_png_file(const std::string& path) {
  File f(std::fopen(path.c_str(), "rb"));
  return f && has_png_signature(f.get());
}

bool is_png_path(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".png";
}

ImageBackend& png_backend() {
  static PngBackend backend;
  return backend;
}

}  // namespace envkit::detail
