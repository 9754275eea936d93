// libFuzzer target: envkit's PNG reader (libpng, libenv/io/src/image_io_png.cpp) on raw bytes, then the writer.
//
// The input is the file, with PNG's signature put over its first 8 bytes (so that every input reaches libpng, not
// the OpenImageIO module that read_image uses for other files). It is read with read_image (small size limits: 1024 per
// side, 2^16 texels); a file that reads is written back as 8- and 16-bit PNG and read again, and must keep its size.
// Every failure must be an envkit::Error whose message names the path, on one line; anything else is a finding
// (__builtin_trap after printing it). libpng's errors arrive through longjmp, so this is also where a broken setjmp
// discipline shows.
#include <envkit/core/error.h>
#include <envkit/io/image_io.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "fuzz_support.h"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

void expect_clean_error(const envkit::Error& e, const std::string& path) {
  const std::string what = e.what();
  if (what.rfind(path + ": ", 0) != 0) finding("error does not name the file: " + what);
  if (what.find('\n') != std::string::npos) finding("error spans lines: " + what);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  ::unsetenv("OCIO");
  ::unsetenv("ENVKIT_OCIO_CONFIG");
  envkit::fuzz::scratch_dir("png");
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const char kSignature[8] = {'\x89', 'P', 'N', 'G', '\r', '\n', '\x1a', '\n'};
  std::string bytes(reinterpret_cast<const char*>(data), size);
  bytes.replace(0, std::min<std::size_t>(8, bytes.size()), kSignature, 8);
  const std::string path = (envkit::fuzz::scratch_dir() / "in.png").string();
  std::ofstream(path, std::ios::binary) << bytes;
  envkit::ReadOptions options;
  options.max_side = 1024;
  options.max_texels = std::int64_t(1) << 16;
  envkit::Image image;
  try {
    image = envkit::read_image(path, options);
  } catch (const envkit::Error& e) {
    expect_clean_error(e, path);
    return 0;
  }
  for (envkit::PixelType type : {envkit::PixelType::UInt8, envkit::PixelType::UInt16}) {
    const std::string out = (envkit::fuzz::scratch_dir() / "out.png").string();
    envkit::WriteOptions w;
    w.pixel_type = type;
    try {
      envkit::write_image(out, image, w);
      const envkit::Image back = envkit::read_image(out, options);
      if (back.width != image.width || back.height != image.height) finding("the written PNG changed size");
    } catch (const envkit::Error& e) {
      finding(std::string("a PNG that read could not be written back: ") + e.what());
    }
  }
  return 0;
}
