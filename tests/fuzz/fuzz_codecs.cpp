// libFuzzer target: envkit's own Radiance and PFM decoders (image_codecs.h) on raw bytes, in memory.
//
// Input: the file's bytes. Radiance files ("#?") are parsed and, when the header's size is small (at most 2^16 texels),
// decoded; PFM headers ("PF"/"Pf") are parsed and the bytes after them decoded when they are enough. Every failure must
// be an envkit::Error naming the file ("fuzz.hdr: ..."); a decoded image must have the header's size and only finite,
// non-negative (Radiance) values. Anything else is a finding.
#include <envkit/core/error.h>
#include <envkit/io/image_codecs.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <span>
#include <string>

#include "fuzz_support.h"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

void check_error(const envkit::Error& e, const char* name) {
  if (std::string(e.what()).rfind(std::string(name) + ": ", 0) != 0) finding(std::string("unnamed error: ") + e.what());
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const unsigned char> bytes(data, size);
  try {
    if (envkit::looks_like_radiance(bytes)) {
      const envkit::RadianceHeader h = envkit::parse_radiance_header(bytes, "fuzz.hdr");
      if (std::int64_t(h.width) * h.height > (1 << 16)) return 0;
      const envkit::Image img = envkit::decode_radiance(bytes, h, "fuzz.hdr");
      if (img.width != h.width || img.height != h.height || img.channels != 3 ||
          img.pixels.size() != img.texel_count() * 3)
        finding("decoded image does not match the header");
      for (float v : img.pixels)
        if (!std::isfinite(v) || v < 0.0f) finding("non-finite or negative value decoded");
    } else if (envkit::looks_like_pfm(bytes)) {
      const envkit::PfmHeader h = envkit::parse_pfm_header(bytes, "fuzz.pfm");
      if (std::int64_t(h.width) * h.height > (1 << 16) || h.data_offset + h.data_bytes() > size) return 0;
      envkit::FloatBuffer floats(h.data_bytes() / sizeof(float));
      std::memcpy(floats.data(), data + h.data_offset, h.data_bytes());
      const envkit::Image img = envkit::decode_pfm(std::move(floats), h);
      if (img.pixels.size() != img.texel_count() * static_cast<std::size_t>(h.channels)) finding("PFM size mismatch");
    }
  } catch (const envkit::Error& e) {
    check_error(e, envkit::looks_like_radiance(bytes) ? "fuzz.hdr" : "fuzz.pfm");
  } catch (const std::exception& e) {
    finding(std::string("exception other than envkit::Error: ") + e.what());
  }
  return 0;
}
