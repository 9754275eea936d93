// libFuzzer target: envrender's scene JSON loader (renderer/src/scene_loader.cpp).
//
// Input: the text of a scene file, loaded with --bake semantics (tables baked in memory). A load must either throw
// envkit::Error whose message starts with the scene's file name, or give a scene with a camera and a light.
// Anything else (another exception type, a crash, a sanitizer report) is a finding.
// Cost limit: inputs with a number above 512 (or an exponent, or 0x) are skipped, so probe sizes and camera
// resolutions stay small; meshes named by the input cannot escape the scratch directory (no '/' or '..').
#include <envkit/core/error.h>
#include <envkit/render/scene_loader.h>

#include <cctype>
#include <cstdint>
#include <cstdio>
#include <string>

#include "fuzz_support.h"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

bool too_costly(const std::string& text) {
  long number = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (std::isdigit(static_cast<unsigned char>(c))) {
      number = number * 10 + (c - '0');
      if (number > 512) return true;
    } else {
      if ((c == 'e' || c == 'E' || c == 'x' || c == 'X') && i > 0 &&
          std::isdigit(static_cast<unsigned char>(text[i - 1])))
        return true;
      number = 0;
    }
  }
  return text.find('/') != std::string::npos || text.find("..") != std::string::npos;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  if (size > 4096 || too_costly(text)) return 0;
  const std::string path = (envkit::fuzz::scratch_dir("scene") / "scene.json").string();
  envkit::render::SceneLoadOptions options;
  options.bake = true;
  envkit::fuzz::SilenceStreams quiet;
  try {
    const envkit::render::LoadedScene loaded = envkit::render::load_scene_text(text, path, options);
    if (!loaded.scene || !loaded.light) finding("a scene loaded without geometry or light");
  } catch (const envkit::Error& e) {
    if (std::string(e.what()).rfind(path, 0) != 0) finding(std::string("error does not name the scene: ") + e.what());
  } catch (const std::exception& e) {
    finding(std::string("non-envkit exception: ") + e.what());
  }
  return 0;
}
