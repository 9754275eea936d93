// The bad-input corpus: a table-driven test over tests/bad-inputs/cases.json. Every case runs one built
// tool on an input made for it (written here at test time: truncated, corrupt, non-finite, wrongly shaped, absurdly
// sized, missing, ...) and asserts the exit code, that stderr is the expected number of lines (one for errors) and
// that its first line matches a regex naming the file and the problem, and that no output or temporary file
// appeared in the work directory (or, for cases that succeed, exactly the listed outputs). The manifest format is
// documented in tests/bad-inputs/README.md. Cases whose tool is not built (envrender with
// -DENVKIT_BUILD_RENDERER=OFF) are skipped.
//
// Also here: tools interrupted by SIGTERM / SIGINT in the middle of a long write leave neither the output nor a
// temporary file (libenv's signal cleanup is tested in-process by test_atomic_file; this runs the real tools).
#include <OpenImageIO/imageio.h>
#include <envkit/core/image.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "cli_support.h"

extern char** environ;

namespace fs = std::filesystem;
using envkit::Image;
using envkit::test::CommandResult;
// ordered: a case's "make" entries are written in the order listed (a later one may replace a file an earlier
// one wrote, e.g. the environment map next to a scene).
using json = nlohmann::ordered_json;

namespace {

const fs::path kCorpusDir = fs::path(ENVKIT_SOURCE_DIR) / "tests" / "bad-inputs";

// ---- input generators ------------------------------------------------------------------------------------------

/// A w x h map, smooth positive values (channel c of texel (x, y) = 0.1 + (x + 2y + c) / (w + h)).
Image smooth(int w, int h, int channels = 3) {
  Image img(w, h, channels);
  img.channel_names = envkit::default_channel_names(channels);
  if (channels == 2 || channels == 4) img.alpha_channel = channels - 1;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c)
        img.at(x, y, c) = c == img.alpha_channel ? 1.0f : 0.1f + float(x + 2 * y + c) / float(w + h);
  return img;
}

void write_tagged(const fs::path& p, const Image& img, const std::string& kind, bool uncompressed = false) {
  envkit::WriteOptions opt;
  if (!kind.empty()) opt.metadata["envkit:parameterization"] = kind;
  if (uncompressed && p.extension() == ".exr") opt.compression = "none";
  envkit::write_image(p.string(), img, opt);
}

/// Float pixels written with OIIO directly: what envkit refuses to write (NaN, Inf, 5 channels).
void write_with_oiio(const fs::path& p, int w, int h, int channels, const std::vector<float>& px) {
  OIIO::ImageSpec spec(w, h, channels, OIIO::TypeDesc::FLOAT);
  auto out = OIIO::ImageOutput::create(p.string());
  if (!out || !out->open(p.string(), spec) || !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
    throw std::runtime_error("cannot write " + p.string() + " with OIIO");
}

std::string slurp(const fs::path& p) { return envkit::test::read_text(p); }
void spit(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

/// A 1x1 EXR (zip: 16 scanlines per chunk) whose data and display windows are patched to claim w x h, followed by
/// a zeroed line-offset table of the claimed size (so OpenEXR opens it and envkit's size check is what refuses it);
/// the pixel data is missing.
void write_exr_claiming(const fs::path& p, int w, int h) {
  write_tagged(p, smooth(1, 1), "");
  std::string bytes = slurp(p);
  if (h > 0) bytes.append(8 * ((static_cast<std::size_t>(h) + 15) / 16) + 64, '\0');
  for (const char* attr : {"dataWindow", "displayWindow"}) {
    const std::string key = std::string(attr) + '\0' + "box2i" + '\0';
    const auto pos = bytes.find(key);
    if (pos == std::string::npos) throw std::runtime_error(std::string("no ") + attr + " in the EXR header");
    const std::int32_t box[4] = {0, 0, w - 1, h - 1};  // after the 4-byte attribute size
    std::memcpy(&bytes[pos + key.size() + 4], box, sizeof box);
  }
  spit(p, bytes);
}

std::string radiance_header(int w, int h) {
  return "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(h) + " +X " + std::to_string(w) + "\n";
}

/// A valid table file baked from a tagged 16x8 lat-long (every method), as envbake would write it.
void write_table(const fs::path& p) {
  envkit::EnvMap map;
  map.image = smooth(16, 8);
  map.param = std::make_unique<envkit::LatLongMap>(16, 8);
  envkit::EnvTables::bake(map, envkit::BakeOptions{}, "src.exr").save(p.string());
}

/// scene:VARIANT: a tiny envrender scene at `p` (4x2 pixels, one diffuse sphere seen from outside). VARIANT `image`
/// (and every variant but `probe`) is lit by sky.exr, a tagged 16x8 lat-long written next to the scene, with
/// sky.envtbl baked from that file (its source hash matches, as envbake writes it); `probe` by a constant 8x4 probe
/// (no other file). The other variants each break one thing of `image`: `malformed` (a ',' on line 4), `unknown_key`
/// (camera.zoom, line 2), `unknown_material` (shapes[0] uses 'gold', line 8), `missing_mesh` (shapes[1] is
/// nowhere.obj, line 9), `no_tables` (no 'tables' key, line 3), `huge` (camera resolution 1000000 x 1000000).
void write_scene(const fs::path& p, const std::string& variant) {
  static const std::set<std::string> variants = {
      "image", "probe", "malformed", "no_tables", "unknown_key", "unknown_material", "missing_mesh", "huge"};
  if (!variants.count(variant)) throw std::runtime_error("unknown scene variant '" + variant + "'");
  const bool probe = variant == "probe";
  const std::string resolution = variant == "huge" ? "[1000000, 1000000]" : "[4, 2]";
  const std::string env = probe                    ? R"("probe": "constant", "radiance": 0.5, "size": [8, 4])"
                          : variant == "no_tables" ? R"("image": "sky.exr")"
                                                   : R"("image": "sky.exr", "tables": "sky.envtbl")";
  std::string text = "{\n";
  text += R"(  "camera": {"position": [0, 1, -5], "look_at": [0, 0.5, 0], "fov": 40, "resolution": )" + resolution +
          (variant == "unknown_key" ? ", \"zoom\": 2},\n" : "},\n");
  text += "  \"environment\": {" + env + "},\n";
  text += variant == "malformed" ? "  \"materials\": {,\n" : "  \"materials\": {\n";
  text += "    \"white\": {\"type\": \"diffuse\", \"albedo\": 0.5}\n  },\n  \"shapes\": [\n";
  text += R"(    {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": ")" +
          std::string(variant == "unknown_material" ? "gold" : "white") + "\"}";
  if (variant == "missing_mesh")
    text +=
        ",\n"
        R"(    {"type": "mesh", "file": "nowhere.obj", "material": "white"})";
  text += "\n  ]\n}\n";
  spit(p, text);
  if (probe) return;
  const fs::path sky = p.parent_path() / "sky.exr";
  write_tagged(sky, smooth(16, 8), "latlong");
  const envkit::EnvMap map = envkit::load_envmap(sky.string());
  envkit::EnvTables::bake(map, envkit::BakeOptions{}, sky.string(), envkit::file_content_hash({sky.string()}))
      .save((p.parent_path() / "sky.envtbl").string());
}

/// merl:ok|dims|truncated|long|nan|negative: a MERL binary BRDF (three int32 dimensions 90 90 180, then 3 x 90 x 90 x
/// 180 doubles) of constant value, or spoiled as named (dims 90 90 360, half the values, 8 trailing bytes, one NaN, all
/// values -1).
void write_merl(const fs::path& p, const std::string& variant) {
  if (!std::set<std::string>{"ok", "dims", "truncated", "long", "nan", "negative"}.count(variant))
    throw std::runtime_error("unknown merl variant '" + variant + "'");
  const std::int32_t dims[3] = {90, 90, variant == "dims" ? 360 : 180};
  std::vector<double> values(std::size_t(3) * 90 * 90 * 180, variant == "negative" ? -1.0 : 100.0);
  if (variant == "nan") values[1000] = std::numeric_limits<double>::quiet_NaN();
  if (variant == "truncated") values.resize(values.size() / 2);
  std::string bytes(reinterpret_cast<const char*>(dims), sizeof dims);
  bytes.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(double));
  if (variant == "long") bytes.append(8, '\0');
  spit(p, bytes);
}

/// Makes file `p` from a generator description (see tests/bad-inputs/README.md). "truncate:G" and "corrupt:G"
/// first make G (written uncompressed when it is an EXR, so the cut lands in pixel data), then damage it.
void generate(const fs::path& p, const std::string& gen) {
  const auto colon = gen.find(':');
  const std::string head = gen.substr(0, colon), arg = colon == std::string::npos ? "" : gen.substr(colon + 1);
  if (head == "truncate" || head == "corrupt" || head == "corrupt_header" || head == "table_version") {
    const fs::path tmp = p.parent_path() / (".gen" + p.extension().string());
    if (arg == "latlong")
      write_tagged(tmp, smooth(64, 32), "latlong", /*uncompressed=*/head == "truncate");
    else
      generate(tmp, head == "table_version" ? "table" : arg);
    std::string bytes = slurp(tmp);
    fs::remove(tmp);
    if (head == "table_version") {  // table_version:N: the uint32 format version after the 8-byte magic
      const std::uint32_t v = static_cast<std::uint32_t>(std::stoul(arg));
      std::memcpy(&bytes[8], &v, sizeof v);
    } else if (head == "truncate") {
      bytes.resize(bytes.size() / 2);
    } else if (head == "corrupt") {  // the middle of the data: XOR 0x5A over [60%, 80%)
      for (std::size_t i = bytes.size() * 6 / 10; i < bytes.size() * 8 / 10; ++i) bytes[i] ^= 0x5A;
    } else {  // the header: bytes [4, 24) (past the magic number)
      for (std::size_t i = 4; i < std::min<std::size_t>(24, bytes.size()); ++i) bytes[i] = '\xff';
    }
    spit(p, bytes);
    return;
  }
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  if (head == "latlong") return write_tagged(p, smooth(16, 8), "latlong");
  if (head == "untagged") return write_tagged(p, smooth(16, 8), "");
  if (head == "cube") return write_tagged(p, smooth(4, 24), "cube");
  if (head == "size") {  // size:WxH[xC] untagged
    int w = 0, h = 0, c = 3;
    if (std::sscanf(arg.c_str(), "%dx%dx%d", &w, &h, &c) < 2) throw std::runtime_error("bad generator " + gen);
    return write_tagged(p, smooth(w, h, c), "");
  }
  if (head == "channels") {  // channels:N, 16x8 float, written with OIIO (envkit writes 1 to 4)
    const int c = std::stoi(arg);
    return write_with_oiio(p, 16, 8, c, std::vector<float>(16 * 8 * c, 0.5f));
  }
  if (head == "nonfinite") {  // nonfinite:nan|inf|-inf|all
    std::vector<float> px(16 * 8 * 3, 1.0f);
    if (arg == "nan" || arg == "all") px[5] = nan;
    if (arg == "inf" || arg == "all") px[17] = inf;
    if (arg == "-inf" || arg == "all") px[30] = -inf;
    return write_with_oiio(p, 16, 8, 3, px);
  }
  if (head == "negative") {
    Image img = smooth(16, 8);
    for (int x = 0; x < 16; ++x) img.at(x, 3, 0) = -1.0f;
    return write_tagged(p, img, "latlong");
  }
  if (head == "sun") {  // sun:V, a tagged 16x8 lat-long with texel (5, 2) at V in every channel
    Image img = smooth(16, 8);
    for (int c = 0; c < 3; ++c) img.at(5, 2, c) = std::stof(arg);
    return write_tagged(p, img, "latlong");
  }
  if (head == "meta") {  // meta:KEY=VALUE on an untagged 16x8 map
    Image img = smooth(16, 8);
    envkit::WriteOptions opt;
    const auto eq = arg.find('=');
    opt.metadata[arg.substr(0, eq)] = arg.substr(eq + 1);
    envkit::write_image(p.string(), img, opt);
    return;
  }
  if (head == "faces" || head == "faces_mismatch" || head == "faces_missing") {  // p holds a '%'
    for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"}) {
      std::string name = p.filename().string();
      name.replace(name.find('%'), 1, f);
      if (head == "faces_missing" && std::string(f) == "-Y") continue;
      const int n = head == "faces_mismatch" && std::string(f) == "+Z" ? 8 : 4;
      write_tagged(p.parent_path() / name, smooth(n, n), "");
    }
    return;
  }
  if (head == "claim_exr") {  // claim_exr:WxH
    int w = 0, h = 0;
    std::sscanf(arg.c_str(), "%dx%d", &w, &h);
    return write_exr_claiming(p, w, h);
  }
  if (head == "claim_hdr") {
    int w = 0, h = 0;
    std::sscanf(arg.c_str(), "%dx%d", &w, &h);
    return spit(p, radiance_header(w, h) + std::string(64, '\0'));
  }
  if (head == "table") return write_table(p);
  if (head == "scene") return write_scene(p, arg);
  if (head == "merl") return write_merl(p, arg);
  if (head == "text") return spit(p, arg);
  if (head == "empty") return spit(p, "");
  if (head == "dir") return (void)fs::create_directories(p);
  if (head == "symlink") return (void)(fs::remove(p), fs::create_symlink(arg, p));
  if (head == "fifo") return (void)(fs::remove(p), ::mkfifo(p.c_str(), 0600));
  if (head == "file") return (void)fs::copy_file(kCorpusDir / "files" / arg, p, fs::copy_options::overwrite_existing);
  throw std::runtime_error("unknown generator '" + gen + "'");
}

// ---- the manifest ----------------------------------------------------------------------------------------------

struct Case {
  std::string name, tool, requires_tool, stderr_regex, extra_regex, note;
  std::vector<std::string> args, outputs;
  std::vector<std::pair<std::string, std::string>> make;  // file (relative to the work dir) -> generator
  int exit_code = 1;
  int lines = -1;  // -1: 1 for exit code 1, unchecked otherwise
};

/// Test listings show the case name, not the bytes of the struct.
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

std::vector<Case> load_cases() {
  std::ifstream in(kCorpusDir / "cases.json");
  if (!in) return {};
  const json manifest = json::parse(in, nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  std::vector<Case> cases;
  for (const json& c : manifest.at("cases")) {
    Case k;
    k.name = c.at("name").get<std::string>();
    k.tool = c.at("tool").get<std::string>();
    k.requires_tool = c.value("requires", k.tool);
    k.args = c.at("args").get<std::vector<std::string>>();
    k.exit_code = c.at("exit").get<int>();
    k.stderr_regex = c.at("stderr").get<std::string>();
    k.extra_regex = c.value("extra_stderr", "");
    k.lines = c.value("lines", -1);
    k.outputs = c.value("outputs", std::vector<std::string>{});
    k.note = c.value("note", "");
    if (c.contains("make"))
      for (const auto& [file, gen] : c.at("make").items()) k.make.emplace_back(file, gen.get<std::string>());
    cases.push_back(std::move(k));
  }
  return cases;
}

std::string substitute(std::string s, const fs::path& dir) {
  for (std::size_t pos; (pos = s.find("{d}")) != std::string::npos;) s.replace(pos, 3, dir.string());
  return s;
}

/// Every entry under `dir`, recursively, as relative paths (temp files start with '.', and are listed too).
std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) names.insert(fs::relative(e.path(), dir).string());
  return names;
}

class BadInput : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    ::unsetenv("OCIO");
    ::unsetenv("ENVKIT_OCIO_CONFIG");
    root_ = fs::temp_directory_path() / ("envkit_bad_" + std::to_string(::getpid()) + "_" + GetParam().name);
    fs::remove_all(root_);
    fs::create_directories(root_ / "w");
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  fs::path root_;
};

TEST(BadInputManifest, HasAtLeastThirtyCasesWithUniqueNames) {
  const auto cases = load_cases();
  ASSERT_FALSE(cases.empty()) << "cannot read " << (kCorpusDir / "cases.json");
  std::set<std::string> names, tools;
  for (const Case& c : cases) {
    EXPECT_TRUE(names.insert(c.name).second) << "duplicate case name " << c.name;
    EXPECT_TRUE(std::regex_match(c.name, std::regex("[A-Za-z0-9_]+"))) << c.name;
    tools.insert(c.tool);
  }
  EXPECT_GE(cases.size(), 30u);
  for (const char* t : {"envconvert", "envinfo", "envdiff", "envprobe", "envbake", "envsample", "envrender"})
    EXPECT_TRUE(tools.count(t)) << t;
}

TEST_P(BadInput, FailsCleanly) {
  const Case& c = GetParam();
  if (!fs::exists(fs::path(ENVKIT_BIN_DIR) / c.requires_tool))
    GTEST_SKIP() << c.requires_tool << " is not built (slot for a later tool)";
  const fs::path work = root_ / "w";
  for (const auto& [file, gen] : c.make) generate(work / file, gen);
  std::vector<std::string> args;
  for (const auto& a : c.args) args.push_back(substitute(a, work));

  const std::set<std::string> before = listing(work);
  const CommandResult r = envkit::test::run_tool(c.tool, args, root_);
  SCOPED_TRACE(c.tool + " " + ::testing::PrintToString(args) + (c.note.empty() ? "" : "\nnote: " + c.note));

  EXPECT_EQ(r.code, c.exit_code) << "stderr:\n" << r.err;
  std::vector<std::string> lines = r.err_lines();
  if (!c.extra_regex.empty()) {  // a known extra line (see the case's note) is tolerated, not required
    const std::regex extra(c.extra_regex);
    std::erase_if(lines, [&](const std::string& l) { return std::regex_search(l, extra); });
  }
  const int want_lines = c.lines >= 0 ? c.lines : (c.exit_code == 1 ? 1 : -1);
  if (want_lines >= 0) {
    EXPECT_EQ(static_cast<int>(lines.size()), want_lines) << "stderr:\n" << r.err;
  }
  if (!c.stderr_regex.empty()) {
    ASSERT_FALSE(lines.empty()) << "no message on stderr";
    const std::string expected = substitute(c.stderr_regex, work);
    EXPECT_TRUE(std::regex_search(lines[0], std::regex(expected)))
        << "first stderr line:\n  " << lines[0] << "\ndoes not match\n  " << expected;
  }

  std::set<std::string> after = listing(work);
  for (const auto& o : c.outputs) {
    EXPECT_TRUE(after.count(substitute(o, work))) << "expected output " << o << " is missing";
    after.erase(o);
  }
  std::set<std::string> appeared;
  for (const auto& f : after)
    if (!before.count(f)) appeared.insert(f);
  EXPECT_TRUE(appeared.empty()) << "files appeared: " << ::testing::PrintToString(appeared);
  for (const auto& f : before) EXPECT_TRUE(after.count(f) || fs::exists(work / f)) << "an input disappeared: " << f;
}

INSTANTIATE_TEST_SUITE_P(Corpus, BadInput, ::testing::ValuesIn(load_cases()),
                         [](const ::testing::TestParamInfo<Case>& p) { return p.param.name; });

// ---- interrupted writes ----------------------------------------------------------------------------------------

class InterruptedWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    ::unsetenv("OCIO");
    ::unsetenv("ENVKIT_OCIO_CONFIG");
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("envkit_sigterm_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write_tagged(dir_ / "in.exr", smooth(256, 128), "latlong");
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  /// Starts `tool args` (stdout/stderr to files outside dir_), waits until `ready` says so (polling every
  /// millisecond, at most `limit`), sends `sig`, and returns the wait status. `seen` tells whether `ready` fired
  /// before the process exited by itself.
  int run_and_signal(const std::string& tool, const std::vector<std::string>& args, const std::function<bool()>& ready,
                     int sig, bool& seen) {
    const std::string program = std::string(ENVKIT_BIN_DIR) + "/" + tool;
    std::vector<std::string> all{program};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    const std::string out = (dir_.parent_path() / (dir_.filename().string() + ".out")).string();
    const std::string err = (dir_.parent_path() / (dir_.filename().string() + ".err")).string();
    posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid = -1;
    const int rc = posix_spawn(&pid, program.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
      ADD_FAILURE() << "cannot start " << program << ": " << std::strerror(rc);
      return -1;
    }
    seen = false;
    int status = 0;
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - start < std::chrono::seconds(300)) {
      if (::waitpid(pid, &status, WNOHANG) == pid) {
        std::error_code ec;
        fs::remove(out, ec);
        fs::remove(err, ec);
        return status;  // finished before `ready`
      }
      if (ready()) {
        seen = true;
        ::kill(pid, sig);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (!seen) ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    std::error_code ec;
    fs::remove(out, ec);
    fs::remove(err, ec);
    return status;
  }

  bool temp_file_present() const {
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.path().filename().string().find(".tmp-") != std::string::npos) return true;
    return false;
  }
  std::set<std::string> names() const { return listing(dir_); }

  /// Runs `tool args` in `dir` with a file size limit (RLIMIT_FSIZE, `ulimit -f`) of `limit` bytes; returns the
  /// wait status and the tool's stderr.
  int run_with_file_limit(const std::string& tool, const std::vector<std::string>& args, rlim_t limit,
                          std::string& err_text) {
    const std::string program = std::string(ENVKIT_BIN_DIR) + "/" + tool;
    const std::string err = (dir_.parent_path() / (dir_.filename().string() + ".limit.err")).string();
    const pid_t pid = ::fork();
    if (pid == 0) {
      const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, 2);
      const int null = ::open("/dev/null", O_WRONLY);
      ::dup2(null, 1);
      const struct rlimit rl { limit, limit };
      ::setrlimit(RLIMIT_FSIZE, &rl);
      std::vector<std::string> all{program};
      all.insert(all.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (auto& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(program.c_str(), argv.data());
      ::_exit(127);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    std::ifstream in(err);
    err_text.assign(std::istreambuf_iterator<char>(in), {});
    std::error_code ec;
    fs::remove(err, ec);
    return status;
  }

  /// SIGQUIT's default action dumps core: no core file may land in the work directory.
  static void without_core_dumps() {
    const struct rlimit no_core { 0, 0 };
    ::setrlimit(RLIMIT_CORE, &no_core);  // inherited by the tools started
  }

  /// Files the atomic writers leave only while they run: temp files and the backups of a group commit.
  bool leftovers(const fs::path& dir) const {
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      const std::string name = e.path().filename().string();
      if (name.find(".tmp-") != std::string::npos || name.find(".bak-") != std::string::npos) return true;
    }
    return false;
  }

  fs::path dir_;
};

// A 4096x2048 float EXR (100 MB before compression) takes long enough to write that the test catches the temp file.
// SIGQUIT and SIGUSR1 stand for the other terminating signals a user can send (all listed in atomic_file.h).
TEST_F(InterruptedWrite, SigtermDuringTheWriteLeavesNoOutputAndNoTempFile) {
  without_core_dumps();
  for (int sig : {SIGTERM, SIGINT, SIGQUIT, SIGUSR1}) {
    SCOPED_TRACE(strsignal(sig));
    bool seen = false;
    const int status = run_and_signal(
        "envconvert",
        {(dir_ / "in.exr").string(), "-o", (dir_ / "out.exr").string(), "--to", "latlong", "--size", "2048", "--filter",
         "nearest", "-q"},
        [&] { return temp_file_present(); }, sig, seen);
    ASSERT_TRUE(seen) << "envconvert finished (status " << status << ") before its temp file was seen";
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status;
    EXPECT_EQ(names(), std::set<std::string>{"in.exr"}) << "a partial output or a temp file was left";
  }
}

// envprefilter stages its outputs (GGX chain, irradiance, LUT) as temp files and renames them at the end: any
// terminating signal meanwhile leaves none of them, and the process dies by that signal.
TEST_F(InterruptedWrite, EnvprefilterInterruptedBySignalsLeavesNothing) {
  without_core_dumps();
  for (int sig : {SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGPIPE, SIGXCPU, SIGHUP}) {
    SCOPED_TRACE(strsignal(sig));
    bool seen = false;
    const int status = run_and_signal(
        "envprefilter",
        {(dir_ / "in.exr").string(), "-o", (dir_ / "u.ktx2").string(), "--size", "128", "--irradiance",
         (dir_ / "irr.exr").string(), "--lut", (dir_ / "lut.png").string(), "-q"},
        [&] { return temp_file_present(); }, sig, seen);
    ASSERT_TRUE(seen) << "envprefilter finished (status " << status << ") before a temp file was seen";
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "status " << status;
    EXPECT_EQ(names(), std::set<std::string>{"in.exr"}) << "an output or a temp file was left";
  }
}

TEST_F(InterruptedWrite, SigtermWhileWritingSixFacesLeavesNoFace) {
  bool seen = false;
  const int status = run_and_signal(
      "envconvert",
      {(dir_ / "in.exr").string(), "-o", (dir_ / "face_%.exr").string(), "--to", "cube", "--size", "1024", "--filter",
       "nearest", "-q"},
      [&] { return temp_file_present(); }, SIGTERM, seen);
  ASSERT_TRUE(seen) << "envconvert finished (status " << status << ") before a temp file was seen";
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "status " << status;
  EXPECT_EQ(names(), std::set<std::string>{"in.exr"}) << "faces or temp files were left";
}

TEST_F(InterruptedWrite, SigtermDuringResamplingLeavesNothing) {
  // Area filter onto a 4096x2048 lat-long: seconds of computing before anything is written. Signal it 200 ms in.
  const auto start = std::chrono::steady_clock::now();
  bool seen = false;
  const int status = run_and_signal(
      "envconvert",
      {(dir_ / "in.exr").string(), "-o", (dir_ / "out.exr").string(), "--to", "octahedral", "--size", "4096", "-q"},
      [&] { return std::chrono::steady_clock::now() - start > std::chrono::milliseconds(200); }, SIGTERM, seen);
  ASSERT_TRUE(seen) << "envconvert finished (status " << status << ") within 200 ms";
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "status " << status;
  EXPECT_EQ(names(), std::set<std::string>{"in.exr"});
}

TEST_F(InterruptedWrite, SigtermDuringEnvprobeWriteLeavesNothing) {
  bool seen = false;
  const int status = run_and_signal(
      "envprobe", {"gradient", "-o", (dir_ / "probe.exr").string(), "--size", "4096x2048"},
      [&] { return temp_file_present(); }, SIGTERM, seen);
  if (!seen) GTEST_SKIP() << "envprobe finished (status " << status << ") before its temp file was seen";
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << "status " << status;
  EXPECT_EQ(names(), std::set<std::string>{"in.exr"});
}

// Multi-file outputs, interrupted at random moments: EXR + PNG preview (envrender, envprobe --preview), the
// --export-exr set (envinfo), six cube faces (envconvert). After SIGINT or SIGTERM at any moment, the directory
// holds either every output or none, and never a temp or backup file. The moments are drawn from [0, 1.2 x the
// command's own duration] with a fixed seed, so the commit itself is hit as often as the computing before it. The
// duration is the shortest run seen so far (a first run with cold caches or beside a busy test is slower), and
// trials go on until at least two of them interrupted the command, so a slow first run cannot leave the test
// without an interrupted trial.
struct MultiOutput {
  std::string name, tool;
  std::vector<std::string> args;
};

std::vector<MultiOutput> multi_outputs(const fs::path& dir) {
  const std::string d = dir.string() + "/";
  return {
      {"envrender EXR+PNG", "envrender", {"--resolution", "64x36", "--spp", "2", "--bake", "-q", "-o", d + "r.exr"}},
      {"envinfo --export-exr", "envinfo", {d + "t.envtbl", "--export-exr", d + "x"}},
      {"six cube faces", "envconvert", {d + "in.exr", "-o", d + "face_%.exr", "--to", "cube", "--size", "128", "-q"}},
      {"envprobe + preview",
       "envprobe",
       {"gradient", "-o", d + "p.exr", "--preview", d + "p.png", "--size", "256x128"}},
  };
}

std::set<std::string> minus(const std::set<std::string>& a, const std::set<std::string>& b) {
  std::set<std::string> out;
  for (const auto& x : a)
    if (!b.count(x)) out.insert(x);
  return out;
}

TEST_F(InterruptedWrite, SignalsAtRandomMomentsLeaveMultiFileOutputsAllOrNothing) {
  ASSERT_EQ(
      envkit::test::run_tool("envbake", {(dir_ / "in.exr").string(), "-o", (dir_ / "t.envtbl").string(), "-q"}, dir_)
          .code,
      0);
  const std::set<std::string> baseline = names();
  std::mt19937 rng(14);
  for (const MultiOutput& m : multi_outputs(dir_)) {
    SCOPED_TRACE(m.name);
    // Two undisturbed runs: what "all" is, and how long the command takes once its files are in the page cache.
    double seconds = 1e9;
    std::set<std::string> all;
    for (int warm = 0; warm < 2; ++warm) {
      const auto t0 = std::chrono::steady_clock::now();
      bool seen = false;
      const int status = run_and_signal(
          m.tool, m.args, [] { return false; }, SIGTERM, seen);
      seconds = std::min(seconds, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
      all = minus(names(), baseline);
      ASSERT_GE(all.size(), 2u) << "a multi-file output";
      for (const auto& f : all) fs::remove(dir_ / f);
    }
    int interrupted = 0;
    for (int trial = 0; trial < 16 && (trial < 4 || interrupted < 2); ++trial) {
      const double delay = std::uniform_real_distribution<double>(0.0, 1.2 * seconds)(rng);
      const int sig = trial % 2 ? SIGINT : SIGTERM;
      const auto start = std::chrono::steady_clock::now();
      bool seen = false;
      const int status = run_and_signal(
          m.tool, m.args,
          [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > delay; }, sig,
          seen);
      const std::set<std::string> produced = minus(names(), baseline);
      EXPECT_FALSE(leftovers(dir_)) << "trial " << trial << ": a temp or backup file was left";
      if (seen && WIFSIGNALED(status)) {
        ++interrupted;
        EXPECT_EQ(WTERMSIG(status), sig);
        EXPECT_TRUE(produced.empty() || produced == all)
            << "trial " << trial << " after " << delay << " s: " << produced.size() << " of " << all.size()
            << " outputs";
      } else {
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
        EXPECT_EQ(produced, all) << "a run that finished wrote every output";
        seconds = std::min(seconds, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
      for (const auto& f : produced) fs::remove(dir_ / f);
    }
    EXPECT_GE(interrupted, 2) << "trials that interrupted the command";
  }
}

// The file size limit (ulimit -f, SIGXFSZ): the write fails (EFBIG) instead of the process being killed, and the
// command exits 1 with one line naming an output, leaving no output and no temp file.
TEST_F(InterruptedWrite, FileSizeLimitLeavesNoOutput) {
  ASSERT_EQ(
      envkit::test::run_tool("envbake", {(dir_ / "in.exr").string(), "-o", (dir_ / "t.envtbl").string(), "-q"}, dir_)
          .code,
      0);
  const std::set<std::string> baseline = names();
  for (const MultiOutput& m : multi_outputs(dir_)) {
    SCOPED_TRACE(m.name);
    std::string err;
    const int status = run_with_file_limit(m.tool, m.args, 4096, err);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << "status " << status << ": " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_NE(err.find(dir_.string()), std::string::npos) << "names the output: " << err;
    EXPECT_EQ(names(), baseline) << err;
    EXPECT_FALSE(leftovers(dir_));
  }
}

// A full disk (ENOSPC) on a 192 KiB tmpfs: same promise. Mounting needs root; without it the same scenario runs
// under a file size limit, so the clause is still exercised.
TEST_F(InterruptedWrite, FullDiskLeavesNoOutput) {
  const fs::path full = dir_ / "full";
  fs::create_directories(full);
  write_tagged(full / "in.exr", smooth(64, 32), "latlong");
  // The input must fit: copy it in before the disk is full, then fill the rest by the outputs.
  const bool mounted = ::mount("tmpfs", full.c_str(), "tmpfs", 0, "size=192k") == 0;
  if (mounted) write_tagged(full / "in.exr", smooth(64, 32), "latlong");
  const std::set<std::string> before = listing(full);
  const std::vector<std::vector<std::string>> commands = {
      {"envconvert", (full / "in.exr").string(), "-o", (full / "face_%.exr").string(), "--to", "cube", "--size", "256",
       "-q"},
      {"envrender", "--resolution", "400x225", "--spp", "1", "--bake", "-q", "-o", (full / "r.exr").string()},
  };
  for (const auto& c : commands) {
    SCOPED_TRACE(c[0] + (mounted ? " on a full tmpfs" : " under a file size limit"));
    std::string err;
    int status = 0;
    if (mounted) {
      const envkit::test::CommandResult r =
          envkit::test::run_tool(c[0], std::vector<std::string>(c.begin() + 1, c.end()), dir_);
      status = r.code == 1 ? 0x100 : -1;
      err = r.err;
    } else {
      status = run_with_file_limit(c[0], std::vector<std::string>(c.begin() + 1, c.end()), 65536, err);
    }
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << err;
    EXPECT_NE(err.find(full.string()), std::string::npos) << "names the output: " << err;
    EXPECT_EQ(listing(full), before) << err;
    EXPECT_FALSE(leftovers(full));
  }
  if (mounted) ::umount(full.c_str());
}

// A failed write names the user's file and the cause, for every kind of writer (text, KTX2, OpenEXR through the
// staged outputs of envprefilter and through envconvert, table files): one stderr line
// "<tool>: <output>: cannot write: <strerror>", never a temp name, and nothing left behind. Under a file size limit
// (EFBIG, "File too large") always; on a full 16 KiB tmpfs (ENOSPC) where mounting is allowed (root).
TEST_F(InterruptedWrite, WriteErrorsNameTheOutputAndTheCause) {
  const std::string in = (dir_ / "in.exr").string(), tables = (dir_ / "t.envtbl").string();
  ASSERT_EQ(envkit::test::run_tool("envbake", {in, "-o", tables, "-q"}, dir_).code, 0);
  const fs::path out = dir_ / "out";
  fs::create_directories(out);
  const bool mounted = ::mount("tmpfs", out.c_str(), "tmpfs", 0, "size=16k") == 0;
  struct Writer {
    std::string output;
    std::vector<std::string> command;
  };
  const std::string o = out.string() + "/";
  const std::vector<Writer> writers = {
      {o + "s.csv", {"envsample", tables, "-o", o + "s.csv", "-n", "20000", "-q"}},
      {o + "u.ktx2", {"envprefilter", in, "-o", o + "u.ktx2", "--size", "64", "-q"}},
      {o + "irr.exr", {"envprefilter", in, "--irradiance", o + "irr.exr", "--irradiance-size", "64", "-q"}},
      {o + "c.exr", {"envconvert", in, "-o", o + "c.exr", "--to", "latlong", "--compression", "none", "-q"}},
      {o + "b.envtbl", {"envbake", in, "-o", o + "b.envtbl", "-q"}},
  };
  for (const bool full_disk : {false, true}) {
    if (full_disk && !mounted) continue;
    const std::string cause = std::strerror(full_disk ? ENOSPC : EFBIG);
    for (const Writer& w : writers) {
      SCOPED_TRACE(w.command[0] + " " + w.output + (full_disk ? " on a full tmpfs" : " under a file size limit"));
      const std::vector<std::string> args(w.command.begin() + 1, w.command.end());
      std::string err;
      int status = 0;
      if (full_disk) {
        const CommandResult r = envkit::test::run_tool(w.command[0], args, dir_);
        status = r.code == 1 ? 0x100 : -1;
        err = r.err;
      } else {
        status = run_with_file_limit(w.command[0], args, 4096, err);
      }
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << "status " << status << ": " << err;
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
      EXPECT_EQ(err.rfind(w.command[0] + ": " + w.output + ": cannot write: ", 0), 0u) << err;
      EXPECT_NE(err.find(cause), std::string::npos) << "says why: " << err;
      EXPECT_EQ(err.find(".tmp-"), std::string::npos) << "no temp name: " << err;
      EXPECT_TRUE(fs::is_empty(out)) << "nothing left in " << out;
    }
  }
  if (mounted) ::umount(out.c_str());
}

}  // namespace
