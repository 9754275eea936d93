// libFuzzer target: the command-line handling of one envkit tool, in process.
//
// The tool's own source (tools/<tool>.cpp, probes/envprobe.cpp) is compiled into this target with
// -Dmain=envkit_tool_main (tests/fuzz/CMakeLists.txt), so the fuzzer drives exactly the code of the shipped
// binary: CLI11 parsing, validators, the combination checks, and the run itself on small files.
//
// Input: the arguments, separated by '\n' or '\0' (at most 32 of at most 256 bytes). argv[0] is the tool name.
// Confinement: the process works in a private scratch directory (chdir) holding small seed maps (in.exr,
// cube.exr, face_%.exr, ...; see write_seed_files); every '/' in an argument becomes '_', so no argument can name
// a path outside that directory (".." is a directory, which the tools refuse to write). Files the run creates are
// removed afterwards and seed files it replaced (--force) are restored, so runs do not depend on each other.
// Cost limit: inputs with a number above kMaxNumber (or written with an exponent or a 0x prefix) are skipped, so
// that "--size 100000" does not make every run allocate gigabytes; without --size, envprobe gets "--size 16x8"
// appended (its default is 1024x512), and inputs asking it for more than 4096 texels or checker cells are skipped
// (envprobe_too_costly). envrender renders tiny scenes of the scratch directory (scene.json,
// probe.json, ...; see write_scene_files): it gets "--resolution 4x2", "--spp 1" and "--scene probe.json" when they
// are absent (the built-in default scene bakes a 1024x512 probe: inputs giving an empty --scene, which means the
// default scene too, are skipped), and inputs asking for more than a few samples are skipped (envrender_too_costly).
// See tests/fuzz/README.md.
#include <envkit/core/image.h>
#include <envkit/envmap/envmap.h>

#include "fuzz_support.h"
#if __has_include(<envkit/tables/env_tables.h>)
#include <envkit/tables/env_tables.h>
#define ENVKIT_FUZZ_HAVE_TABLES 1
#endif
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#ifndef ENVKIT_FUZZ_TOOL
#error "ENVKIT_FUZZ_TOOL must name the tool (set by tests/fuzz/CMakeLists.txt)"
#endif

int envkit_tool_main(int argc, char** argv);

namespace {

namespace fs = std::filesystem;
constexpr std::size_t kMaxArgs = 32, kMaxArgLength = 256;
constexpr long kMaxNumber = 512;

struct Seed {
  std::string bytes;
  struct stat st {};
};
std::map<std::string, Seed> g_seeds;  // file name -> contents and stat after writing

envkit::Image gradient(int w, int h, int channels, float scale = 1.0f) {
  envkit::Image img(w, h, channels);
  img.channel_names = envkit::default_channel_names(channels);
  if (channels == 2 || channels == 4) img.alpha_channel = channels - 1;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c)
        img.at(x, y, c) = c == img.alpha_channel ? 1.0f : scale * (0.1f + float(x + 2 * y + c) / float(w + h));
  return img;
}

void write_tagged(const std::string& name, const envkit::Image& img, const std::string& kind) {
  envkit::WriteOptions opt;
  if (!kind.empty()) opt.metadata["envkit:parameterization"] = kind;
  envkit::write_image(name, img, opt);
}

/// envrender's scenes (4x2 pixels): scene.json lit by in.exr through in.envtbl, every material and shape type
/// (mesh.obj is a tetrahedron); probe.json, a sun probe; stale.json, plain.exr with in.envtbl (stale unless --bake);
/// cube.json and faces.json, a cube strip and six face files without tables (need --bake); bad.json, malformed.
void write_scene_files() {
  auto scene = [](const std::string& name, const std::string& environment) {
    std::ofstream(name, std::ios::binary)
        << R"({"camera": {"position": [0, 1, -5], "look_at": [0, 0.5, 0], "fov": 40, "resolution": [4, 2]},)"
           "\n"
        << R"( "environment": {)" << environment << "},\n"
        << R"( "materials": {"d": {"type": "diffuse", "albedo": 0.5}, "c": {"type": "conductor", "roughness": 0.2},)"
        << R"( "p": {"type": "plastic", "roughness": 0.05}, "m": {"type": "mirror"}},)"
           "\n"
        << R"( "shapes": [{"type": "triangles", "material": "d", "triangles": [[0, 2, 1], [0, 3, 2]],)"
           "\n"
        << R"(             "vertices": [[-9, 0, -9], [9, 0, -9], [9, 0, 9], [-9, 0, 9]]},)"
           "\n"
        << R"(            {"type": "sphere", "center": [-1, 0.5, 0], "radius": 0.5, "material": "c"},)"
           "\n"
        << R"(            {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "p"},)"
           "\n"
        << R"(            {"type": "mesh", "file": "mesh.obj", "material": "m"}]})"
           "\n";
  };
  std::ofstream("mesh.obj", std::ios::binary)
      << "v 1 0 0\nv 2 0 0\nv 1.5 0 1\nv 1.5 1 0.4\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n";
  scene("scene.json", R"("image": "in.exr", "tables": "in.envtbl", "rotation": [90, 0, 0], "intensity": 2)");
  scene("probe.json", R"("probe": "sun", "size": [16, 8], "radiance": 100, "sky": 0.5)");
  scene("stale.json", R"("image": "plain.exr", "tables": "in.envtbl")");
  scene("cube.json", R"("image": "cube.exr")");
  scene("faces.json", R"("image": "face_%.exr", "convention": "gl")");
  std::ofstream("bad.json", std::ios::binary) << "{\"camera\": {,}\n";
}

void write_seed_files() {
  write_tagged("in.exr", gradient(16, 8, 3), "latlong");
  write_tagged("plain.exr", gradient(16, 8, 3), "");
  write_tagged("in.hdr", gradient(16, 8, 3), "");
  write_tagged("in.png", gradient(16, 8, 4), "");
  write_tagged("gray.exr", gradient(16, 8, 1), "");
  write_tagged("neg.exr", gradient(16, 8, 3, -1.0f), "latlong");
  write_tagged("cube.exr", gradient(4, 24, 3), "cube");
  write_tagged("cross.exr", gradient(16, 12, 3), "");
  write_tagged("sq.exr", gradient(8, 8, 3), "");
  write_tagged("one.exr", gradient(1, 1, 3), "");
  write_tagged("odd.exr", gradient(7, 5, 3), "");
  envkit::Image ball = gradient(16, 16, 3);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      if ((x - 7.5) * (x - 7.5) + (y - 7.5) * (y - 7.5) > 64.0)
        for (int c = 0; c < 3; ++c) ball.at(x, y, c) = 0.0f;
  write_tagged("ball.exr", ball, "");
  for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"})
    write_tagged(std::string("face_") + f + ".exr", gradient(4, 4, 3), "");
#ifdef ENVKIT_FUZZ_HAVE_TABLES
  {  // a table file for envsample / envinfo / envrender, recording in.exr's file hash as envbake does (fresh)
    envkit::EnvMap map;
    map.image = gradient(16, 8, 3);
    map.param = std::make_unique<envkit::LatLongMap>(16, 8);
    envkit::EnvTables::bake(map, envkit::BakeOptions{}, "in.exr", envkit::file_content_hash({"in.exr"}))
        .save("in.envtbl");
  }
#endif
  if (std::string(ENVKIT_FUZZ_TOOL) == "envrender") write_scene_files();
  std::ofstream("junk.exr", std::ios::binary) << "not an image";
  std::ofstream("empty.exr", std::ios::binary);
  fs::create_directories("dir.exr");
  for (const auto& e : fs::directory_iterator(".")) {
    if (!e.is_regular_file()) continue;
    Seed s;
    std::ifstream in(e.path(), std::ios::binary);
    s.bytes.assign(std::istreambuf_iterator<char>(in), {});
    ::stat(e.path().c_str(), &s.st);
    g_seeds[e.path().filename().string()] = std::move(s);
  }
}

// Removes what the run created and restores seed files it replaced or removed.
void restore_scratch() {
  for (const auto& e : fs::directory_iterator(".")) {
    const std::string name = e.path().filename().string();
    if (name == "dir.exr") continue;
    if (!g_seeds.count(name)) fs::remove_all(e.path());
  }
  fs::create_directories("dir.exr");
  for (auto& [name, seed] : g_seeds) {
    struct stat st {};
    if (::stat(name.c_str(), &st) == 0 && st.st_ino == seed.st.st_ino && st.st_size == seed.st.st_size &&
        st.st_mtim.tv_sec == seed.st.st_mtim.tv_sec && st.st_mtim.tv_nsec == seed.st.st_mtim.tv_nsec)
      continue;
    fs::remove_all(name);
    std::ofstream(name, std::ios::binary) << seed.bytes;
    ::stat(name.c_str(), &seed.st);
  }
}

// True when the argument holds a number that could make the run expensive (see the file comment).
bool too_costly(const std::string& a) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    const char c = a[i];
    if (c >= '0' && c <= '9') {
      long v = 0;
      std::size_t j = i;
      while (j < a.size() && a[j] >= '0' && a[j] <= '9' && v <= kMaxNumber) v = v * 10 + (a[j++] - '0');
      if (v > kMaxNumber) return true;
      if (c == '0' && i + 1 < a.size() && (a[i + 1] == 'x' || a[i + 1] == 'X' || a[i + 1] == 'b' || a[i + 1] == 'o'))
        return true;
      if (j < a.size() && (a[j] == 'e' || a[j] == 'E')) return true;
      while (j < a.size() && a[j] >= '0' && a[j] <= '9') ++j;
      i = j;
    }
  }
  return false;
}

/// The values given to option `name` ("--name V" or "--name=V"); `present` tells whether it appears at all.
std::vector<std::string> option_values(const std::vector<std::string>& args, const std::string& name, bool& present) {
  std::vector<std::string> values;
  present = false;
  for (std::size_t i = 1; i < args.size(); ++i) {
    if (args[i] == name) {
      present = true;
      if (i + 1 < args.size()) values.push_back(args[i + 1]);
    } else if (args[i].rfind(name + "=", 0) == 0) {
      present = true;
      values.push_back(args[i].substr(name.size() + 1));
    }
  }
  return values;
}

/// envrender: true when the arguments ask for more than a few samples (every run must stay in milliseconds); adds
/// the forced options (see the file comment) when they are absent. A value holding a digit must be a plain integer
/// (WxH for --resolution) within the limit, or negative (refused by envrender): "1_000" or "+1000" could mean more
/// to CLI11 than to this check. Values without a digit ("abc", "nan") reach envrender's own checks.
bool envrender_too_costly(std::vector<std::string>& args) {
  static const std::map<std::string, long> limits = {
      {"--spp", 4}, {"--max-depth", 4}, {"--bsdf-samples", 8}, {"--light-samples", 8}, {"--threads", 4}};
  auto has_digit = [](const std::string& v) { return v.find_first_of("0123456789") != std::string::npos; };
  auto plain = [](const std::string& v, long limit) {
    const std::size_t start = v.size() > 1 && v[0] == '-' ? 1 : 0;
    if (v.size() == start || v.size() > 6 || v.find_first_not_of("0123456789", start) != std::string::npos)
      return false;
    return std::stol(v) <= limit;
  };
  bool present = false;
  for (const auto& [name, limit] : limits)
    for (const std::string& v : option_values(args, name, present))
      if (has_digit(v) && !plain(v, limit)) return true;
  for (const std::string& v : option_values(args, "--resolution", present)) {
    const auto x = v.find('x');
    if (has_digit(v) && (x == std::string::npos || !plain(v.substr(0, x), 8) || !plain(v.substr(x + 1), 8)))
      return true;
  }
  if (!present) args.insert(args.end(), {"--resolution", "4x2"});
  // --time renders passes until the time is up: at most 20 ms, "inf" never ends (NaN is let through: it must not
  // hang either).
  for (const std::string& v : option_values(args, "--time", present))
    if (std::strtod(v.c_str(), nullptr) > 0.02 ||
        (has_digit(v) && v.find_first_not_of("0123456789.") != std::string::npos))
      return true;
  option_values(args, "--spp", present);
  if (!present) args.insert(args.end(), {"--spp", "1"});
  // The built-in default scene rasterizes and bakes a 1024x512 probe on every run (seconds under ASan); an empty
  // --scene also means the default scene.
  for (const std::string& v : option_values(args, "--scene", present))
    if (v.empty()) return true;
  if (!present) args.insert(args.end(), {"--scene", "probe.json"});
  return false;
}

/// envprobe: true when --size or --cells ask for more than a few thousand texels or cells, or --size is empty
/// (envprobe's default, 1024x512). envprobe integrates each texel over its exact solid angle, so a 512x512 map
/// costs about a second under ASan and reaches no other code than a 16x8 map does. Values that are not plain
/// sizes ("0x0", "-4", "abc", "512x") reach envprobe's own checks.
bool envprobe_too_costly(const std::vector<std::string>& args) {
  constexpr long kMaxTexels = 4096;
  const auto plain = [](const std::string& v) {
    return !v.empty() && v.size() <= 6 && v.find_first_not_of("0123456789") == std::string::npos;
  };
  const auto product = [&](const std::string& v, char sep, long single) -> long {
    const auto at = v.find(sep);
    if (at == std::string::npos) return plain(v) ? single * std::stol(v) * std::stol(v) : 0;
    const std::string a = v.substr(0, at), b = v.substr(at + 1);
    return plain(a) && plain(b) ? std::stol(a) * std::stol(b) : 0;
  };
  bool present = false;
  for (std::string v : option_values(args, "--size", present)) {
    std::replace(v.begin(), v.end(), 'X', 'x');  // WxH takes either case (tools/common/cli.h parse_image_size)
    if (v.empty() || product(v, 'x', 6) > kMaxTexels) return true;  // N: six cube faces of N x N at most
  }
  for (const std::string& v : option_values(args, "--cells", present))
    if (product(v, ',', 1) > kMaxTexels) return true;
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  const fs::path& dir = envkit::fuzz::scratch_dir(ENVKIT_FUZZ_TOOL);
  fs::current_path(dir);
  ::unsetenv("OCIO");
  ::unsetenv("ENVKIT_OCIO_CONFIG");
  write_seed_files();
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::string> args{ENVKIT_FUZZ_TOOL};
  std::string cur;
  for (std::size_t i = 0; i <= size; ++i) {
    if (i == size || data[i] == '\n' || data[i] == '\0') {
      if (args.size() > kMaxArgs || cur.size() > kMaxArgLength) return 0;
      args.push_back(cur);
      cur.clear();
    } else {
      cur += data[i] == '/' ? '_' : static_cast<char>(data[i]);
    }
  }
  if (size == 0) args.pop_back();  // no argument at all
  bool has_size = false;
  for (const auto& a : args) {
    if (too_costly(a)) return 0;
    has_size = has_size || a.rfind("--size", 0) == 0;
  }
  if (std::string(ENVKIT_FUZZ_TOOL) == "envprobe" && !has_size) args.insert(args.end(), {"--size", "16x8"});
  if (std::string(ENVKIT_FUZZ_TOOL) == "envrender" && envrender_too_costly(args)) return 0;
  if (std::string(ENVKIT_FUZZ_TOOL) == "envprobe" && envprobe_too_costly(args)) return 0;

  std::vector<std::vector<char>> storage;
  std::vector<char*> argv;
  for (const auto& a : args) storage.emplace_back(a.c_str(), a.c_str() + a.size() + 1);
  for (auto& s : storage) argv.push_back(s.data());
  argv.push_back(nullptr);
  {
    envkit::fuzz::SilenceStreams quiet;
    const int code = envkit_tool_main(static_cast<int>(args.size()), argv.data());
    // The documented exit codes are 0..3 for every tool.
    if (code < 0 || code > 3) __builtin_trap();
  }
  restore_scratch();
  return 0;
}
