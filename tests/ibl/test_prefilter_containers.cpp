// KTX2 and DDS outputs read back by independent readers: ktx-parse (npm, through node) for KTX2, parse-dds (npm) for
// float DDS cubes; the other DDS formats by Microsoft's documented header fields and by their texels, which must be
// the bytes ktx-parse reads from the KTX2 file of the same levels (OIIO 2.4 reads no float DX10 DDS).
// Known directions on known texels: every texel of every face holds 1 + its direction, checked against the
// GL/Vulkan/D3D cube face table written out here from the specifications (major axis, sc, tc).
#include <Imath/half.h>
#include <envkit/core/clamp_report.h>
#include <envkit/core/error.h>
#include <envkit/ibl/dds.h>
#include <envkit/ibl/exr_cube_mips.h>
#include <envkit/ibl/ktx2.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;
namespace fs = std::filesystem;

namespace {

// The cube face table of the OpenGL 4.6 / Vulkan / D3D specifications: face f, texel (i, j) of an N x N face
// (row j = 0 first, t grows downwards) sees r with s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2.
Vec3 spec_direction(int face, int i, int j, int n) {
  const double sc = 2.0 * (i + 0.5) / n - 1.0, tc = 2.0 * (j + 0.5) / n - 1.0;
  switch (face) {
    case 0:
      return Vec3(1, -tc, -sc).normalized();  // +X: sc = -rz, tc = -ry
    case 1:
      return Vec3(-1, -tc, sc).normalized();  // -X: sc = +rz, tc = -ry
    case 2:
      return Vec3(sc, 1, tc).normalized();  // +Y: sc = +rx, tc = +rz
    case 3:
      return Vec3(sc, -1, -tc).normalized();  // -Y: sc = +rx, tc = -rz
    case 4:
      return Vec3(sc, -tc, 1).normalized();  // +Z: sc = +rx, tc = -ry
    default:
      return Vec3(-sc, -tc, -1).normalized();  // -Z: sc = -rx, tc = -ry
  }
}

Vec3 encode(const Vec3& d) { return Vec3(1.0) + d; }

// Levels of a GL-basis cube whose texels hold 1 + direction.
std::vector<Image> direction_cube(int n) {
  std::vector<Image> levels;
  for (int s = n; s >= 1; s /= 2) {
    const CubeMap cube(s, CubeLayout::VerticalStrip, CubeBasis::GL);
    levels.push_back(rasterize(cube, encode));
  }
  return levels;
}

std::vector<const Image*> pointers(const std::vector<Image>& levels) {
  std::vector<const Image*> p;
  for (const Image& l : levels) p.push_back(&l);
  return p;
}

// Independent decoders written from the Vulkan specification's unsigned 10/11-bit float and shared-exponent rules.
double uf(std::uint32_t v, int mbits) {
  const int e = int(v >> mbits), m = int(v & ((1u << mbits) - 1));
  return e == 0 ? std::pow(2.0, -14) * (m / std::pow(2.0, mbits))
                : std::pow(2.0, e - 15) * (1.0 + m / std::pow(2.0, mbits));
}
Vec3 decode_word(std::uint32_t w, GpuFormat format) {
  if (format == GpuFormat::B10G11R11) return Vec3(uf(w & 0x7ff, 6), uf((w >> 11) & 0x7ff, 6), uf(w >> 22, 5));
  const double scale = std::pow(2.0, int(w >> 27) - 15 - 9);
  return Vec3((w & 0x1ff) * scale, ((w >> 9) & 0x1ff) * scale, ((w >> 18) & 0x1ff) * scale);
}

class Containers : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_containers_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  // What one of the independent readers of tests/js (node scripts) found in `file`.
  nlohmann::json node_dump(const std::string& script, const fs::path& file) {
    const test::CommandResult r =
        test::run_command("node", {std::string(ENVKIT_SOURCE_DIR) + "/tests/js/" + script, file.string()}, dir_);
    EXPECT_EQ(r.code, 0) << r.err;
    return nlohmann::json::parse(r.out);
  }
  nlohmann::json ktx_parse(const fs::path& file) { return node_dump("ktx_dump.mjs", file); }
  fs::path dir_;
};

TEST_F(Containers, Ktx2ReadByKtxParseHasKnownDirectionsOnKnownTexels) {
  const int n = 4;
  const std::vector<Image> levels = direction_cube(n);
  for (GpuFormat format : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9}) {
    SCOPED_TRACE(gpu_format_name(format));
    const fs::path file = dir_ / ("cube_" + gpu_format_name(format) + ".ktx2");
    Ktx2Options o;
    o.format = format;
    o.key_values["envkit:ibl_roughness"] = "0,0.5,1";
    write_ktx2(file.string(), pointers(levels), o);
    const nlohmann::json j = ktx_parse(file);
    const int bytes = gpu_format_bytes(format);
    EXPECT_EQ(j["vkFormat"], vk_format(format));
    EXPECT_EQ(j["typeSize"], format == GpuFormat::Rgba16f ? 2 : 4);
    EXPECT_EQ(j["pixelWidth"], n);
    EXPECT_EQ(j["pixelHeight"], n);
    EXPECT_EQ(j["pixelDepth"], 0);
    EXPECT_EQ(j["layerCount"], 0);
    EXPECT_EQ(j["faceCount"], 6);
    EXPECT_EQ(j["levelCount"], 3);
    EXPECT_EQ(j["supercompressionScheme"], 0);
    const nlohmann::json& dfd = j["dfd"];
    EXPECT_EQ(dfd["vendorId"], 0);
    EXPECT_EQ(dfd["descriptorType"], 0);
    EXPECT_EQ(dfd["versionNumber"], 2);
    EXPECT_EQ(dfd["colorModel"], 1);        // KHR_DF_MODEL_RGBSDA
    EXPECT_EQ(dfd["colorPrimaries"], 1);    // BT.709
    EXPECT_EQ(dfd["transferFunction"], 1);  // linear
    EXPECT_EQ(dfd["bytesPlane"][0], bytes);
    const std::size_t samples = format == GpuFormat::E5B9G9R9 ? 6 : format == GpuFormat::B10G11R11 ? 3 : 4;
    ASSERT_EQ(dfd["samples"].size(), samples);
    EXPECT_EQ(dfd["descriptorBlockSize"], 24 + 16 * samples);
    if (format == GpuFormat::Rgba16f || format == GpuFormat::Rgba32f) {
      const int bits = format == GpuFormat::Rgba16f ? 16 : 32;
      for (int s = 0; s < 4; ++s) {
        EXPECT_EQ(dfd["samples"][s]["bitOffset"], s * bits);
        EXPECT_EQ(dfd["samples"][s]["bitLength"], bits - 1);
        EXPECT_EQ(dfd["samples"][s]["channelType"], (s == 3 ? 15 : s) | 0xC0);  // FLOAT | SIGNED
        EXPECT_EQ(dfd["samples"][s]["sampleUpper"], 0x3F800000);
      }
    } else if (format == GpuFormat::B10G11R11) {
      EXPECT_EQ(dfd["samples"][1]["bitOffset"], 11);
      EXPECT_EQ(dfd["samples"][2]["bitLength"], 9);
      EXPECT_EQ(dfd["samples"][2]["channelType"], 2 | 0x80);
    } else {
      EXPECT_EQ(dfd["samples"][1]["bitOffset"], 27);
      EXPECT_EQ(dfd["samples"][1]["channelType"], 0 | 0x20);  // red, EXPONENT
      EXPECT_EQ(dfd["samples"][4]["bitOffset"], 18);
      EXPECT_EQ(dfd["samples"][0]["sampleUpper"], 8448);
    }
    EXPECT_EQ(j["keyValue"]["KTXwriter"], "envkit");
    EXPECT_EQ(j["keyValue"]["envkit:ibl_roughness"], "0,0.5,1");
    // Level index: level 0 first; data smallest first in the file, aligned to lcm(texel size, 4).
    const nlohmann::json& lv = j["levels"];
    for (int m = 0; m < 3; ++m) {
      const int s = n >> m;
      EXPECT_EQ(lv[m]["byteLength"], 6 * s * s * bytes);
      EXPECT_EQ(lv[m]["uncompressedByteLength"], 6 * s * s * bytes);
      EXPECT_EQ(lv[m]["byteOffset"].get<std::size_t>() % std::size_t(std::max(bytes, 4)), 0u);
    }
    EXPECT_LT(lv[2]["byteOffset"], lv[1]["byteOffset"]);
    EXPECT_LT(lv[1]["byteOffset"], lv[0]["byteOffset"]);
    // Every texel of every face of every level holds 1 + the direction the specification's table gives it.
    for (int m = 0; m < 3; ++m) {
      const int s = n >> m;
      const auto words = lv[m]["words"].get<std::vector<std::uint32_t>>();
      for (int f = 0; f < 6; ++f)
        for (int jj = 0; jj < s; ++jj)
          for (int ii = 0; ii < s; ++ii) {
            const std::size_t t = (std::size_t(f) * s + jj) * s + ii;
            Vec3 got;
            double tol = 1e-6;
            if (format == GpuFormat::Rgba32f) {
              float v[3];
              for (int c = 0; c < 3; ++c) std::memcpy(&v[c], &words[t * 4 + c], 4);
              got = Vec3(v[0], v[1], v[2]);
            } else if (format == GpuFormat::Rgba16f) {
              Imath::half h[3];
              for (int c = 0; c < 3; ++c) h[c].setBits(std::uint16_t(words[t * 4 + c]));
              got = Vec3(h[0], h[1], h[2]);
              tol = 2e-3;
            } else {
              got = decode_word(words[t], format);
              tol = format == GpuFormat::B10G11R11 ? 2.0 / 32 : 2.0 / 256;
            }
            const Vec3 want = encode(spec_direction(f, ii, jj, s));
            EXPECT_NEAR(got.x, want.x, tol) << "level " << m << " face " << f << " texel " << ii << "," << jj;
            EXPECT_NEAR(got.y, want.y, tol) << "level " << m << " face " << f << " texel " << ii << "," << jj;
            EXPECT_NEAR(got.z, want.z, tol) << "level " << m << " face " << f << " texel " << ii << "," << jj;
          }
    }
  }
}

std::uint32_t word(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

TEST_F(Containers, DdsHeaderAndFaceOrderFollowTheDirect3DLayout) {
  // OIIO 2.4's DDS reader refuses every uncompressed DX10 float format ("Unsupported compression type", checked
  // below), so the layout is checked here against Microsoft's documented DDS_HEADER / DDS_HEADER_DXT10 fields.
  const int n = 4;
  const std::vector<Image> levels = direction_cube(n);
  for (GpuFormat format : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9}) {
    SCOPED_TRACE(gpu_format_name(format));
    const fs::path file = dir_ / ("cube_" + gpu_format_name(format) + ".dds");
    DdsOptions o;
    o.format = format;
    write_dds(file.string(), pointers(levels), o);
    const std::string b = test::read_text(file);
    const int bytes = gpu_format_bytes(format);
    ASSERT_EQ(b.substr(0, 4), "DDS ");
    EXPECT_EQ(word(b, 4), 124u);               // dwSize
    EXPECT_EQ(word(b, 12), std::uint32_t(n));  // height
    EXPECT_EQ(word(b, 16), std::uint32_t(n));  // width
    EXPECT_EQ(word(b, 28), 3u);                // mip count
    EXPECT_EQ(word(b, 76), 32u);               // DDS_PIXELFORMAT size
    EXPECT_EQ(b.substr(84, 4), "DX10");
    EXPECT_EQ(word(b, 112) & 0x200u, 0x200u);    // DDSCAPS2_CUBEMAP
    EXPECT_EQ(word(b, 112) & 0xFC00u, 0xFC00u);  // all six faces
    EXPECT_EQ(word(b, 128), dxgi_format(format));
    EXPECT_EQ(word(b, 132), 3u);  // TEXTURE2D
    EXPECT_EQ(word(b, 136), 4u);  // DDS_RESOURCE_MISC_TEXTURECUBE
    EXPECT_EQ(word(b, 140), 1u);  // arraySize
    EXPECT_EQ(b.size(), 148u + std::size_t(6) * (16 + 4 + 1) * bytes);
    // Face-major: face f's level 0 starts after f full chains; its texels follow the face table.
    if (format == GpuFormat::Rgba32f) {
      for (int f = 0; f < 6; ++f)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const std::size_t at = 148 + std::size_t(f) * (16 + 4 + 1) * 16 + (std::size_t(j) * n + i) * 16;
            float v[3];
            std::memcpy(v, b.data() + at, 12);
            const Vec3 want = encode(spec_direction(f, i, j, n));
            EXPECT_NEAR(v[0], want.x, 1e-6) << f;
            EXPECT_NEAR(v[1], want.y, 1e-6) << f;
            EXPECT_NEAR(v[2], want.z, 1e-6) << f;
          }
    }
    if (format == GpuFormat::Rgba32f) {
      const test::CommandResult r = test::run_command("oiiotool", {"--info", file.string()}, dir_);
      EXPECT_NE(r.code, 0) << "OIIO now reads float DX10 DDS files: validate the texels through it";
    }
  }
}

// The float cube read by an independent reader: parse-dds (npm, through node) finds each face's levels, and the
// texels it points at hold the directions of the Direct3D face table.
TEST_F(Containers, DdsReadByParseDdsHasKnownDirectionsOnKnownTexels) {
  const int n = 4, mips = 3;
  const std::vector<Image> levels = direction_cube(n);
  const fs::path file = dir_ / "cube.dds";
  DdsOptions o;
  o.format = GpuFormat::Rgba32f;
  write_dds(file.string(), pointers(levels), o);
  const nlohmann::json j = node_dump("dds_dump.mjs", file);
  EXPECT_EQ(j["format"], "rgba32f");
  EXPECT_TRUE(j["cubemap"].get<bool>());
  ASSERT_EQ(j["images"].size(), std::size_t(6 * mips));
  const std::string b = test::read_text(file);
  for (int f = 0; f < 6; ++f)
    for (int m = 0; m < mips; ++m) {
      SCOPED_TRACE("face " + std::to_string(f) + " level " + std::to_string(m));
      const nlohmann::json& image = j["images"][std::size_t(f * mips + m)];
      const int s = n >> m;
      EXPECT_EQ(image["shape"][0].get<int>(), s);
      EXPECT_EQ(image["shape"][1].get<int>(), s);
      ASSERT_EQ(image["length"].get<std::size_t>(), std::size_t(s) * s * 16);
      const std::size_t offset = image["offset"].get<std::size_t>();
      ASSERT_LE(offset + std::size_t(s) * s * 16, b.size());
      for (int y = 0; y < s; ++y)
        for (int x = 0; x < s; ++x) {
          float v[4];
          std::memcpy(v, b.data() + offset + (std::size_t(y) * s + x) * 16, 16);
          const Vec3 want = encode(spec_direction(f, x, y, s));
          EXPECT_NEAR(v[0], want.x, 1e-6);
          EXPECT_NEAR(v[1], want.y, 1e-6);
          EXPECT_NEAR(v[2], want.z, 1e-6);
        }
    }
}

// The texels of the formats parse-dds does not read (half and the packed ones), anchored to an independent reader all
// the same: the DDS payload, cut at Microsoft's layout (face-major, each face's chain in level order after the
// 148-byte header), holds byte for byte the texels ktx-parse finds in the KTX2 file of the same levels (level-major,
// faces inside), whose texels the KTX2 tests check against the face table.
TEST_F(Containers, DdsTexelsOfEveryFormatAreTheTexelsKtxParseReadsFromTheKtx2File) {
  const int n = 8;
  const std::vector<Image> levels = direction_cube(n);
  for (GpuFormat format : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9}) {
    SCOPED_TRACE(gpu_format_name(format));
    const fs::path ktx = dir_ / ("same_" + gpu_format_name(format) + ".ktx2");
    const fs::path dds = dir_ / ("same_" + gpu_format_name(format) + ".dds");
    Ktx2Options ko;
    ko.format = format;
    write_ktx2(ktx.string(), pointers(levels), ko);
    DdsOptions dopt;
    dopt.format = format;
    write_dds(dds.string(), pointers(levels), dopt);
    const nlohmann::json j = ktx_parse(ktx);
    ASSERT_EQ(j["levels"].size(), levels.size());
    const std::string d = test::read_text(dds);
    const std::size_t texel = std::size_t(gpu_format_bytes(format));
    const std::size_t word_bytes = format == GpuFormat::Rgba16f ? 2 : 4;
    std::size_t chain = 0;  // bytes of one face's whole chain in the DDS file
    for (int s = n; s >= 1; s /= 2) chain += std::size_t(s) * s * texel;
    ASSERT_EQ(d.size(), 148 + 6 * chain);
    std::size_t before = 0;  // bytes of a face's levels above level m
    for (std::size_t m = 0; m < levels.size(); ++m) {
      const std::size_t s = std::size_t(n >> m), face_bytes = s * s * texel;
      const nlohmann::json& words = j["levels"][m]["words"];
      ASSERT_EQ(words.size() * word_bytes, 6 * face_bytes) << m;
      std::string ktx_level(6 * face_bytes, '\0');  // the words ktx-parse read, back to little-endian bytes
      for (std::size_t w = 0; w < words.size(); ++w) {
        const std::uint32_t v = words[w].get<std::uint32_t>();
        for (std::size_t k = 0; k < word_bytes; ++k) ktx_level[w * word_bytes + k] = char((v >> (8 * k)) & 0xff);
      }
      for (std::size_t f = 0; f < 6; ++f)
        EXPECT_EQ(d.compare(148 + f * chain + before, face_bytes, ktx_level, f * face_bytes, face_bytes), 0)
            << "face " << f << " level " << m;
      before += face_bytes;
    }
  }
}

TEST_F(Containers, PackedFormatsRoundTrip) {
  for (float v : {0.0f, 1e-6f, 0.001f, 0.5f, 1.0f, 3.14159f, 1000.0f, 60000.0f}) {
    const float rgb[3] = {v, v * 0.5f, v * 0.25f};
    float back[3];
    unpack_b10g11r11(pack_b10g11r11(rgb), back);
    // Half a mantissa step relative, or the smallest denormal step (2^-14 / 2^mbits) near zero.
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(back[c], rgb[c], c == 2 ? rgb[c] / 64 + std::ldexp(1.0, -19) : rgb[c] / 128 + std::ldexp(1.0, -20))
          << v;
    unpack_e5b9g9r9(pack_e5b9g9r9(rgb), back);
    // Shared exponent: steps of the largest channel's scale (9 mantissa bits), at least 2^-24.
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back[c], rgb[c], v / 512.0 + std::ldexp(1.0, -24)) << v;
  }
  const float big[3] = {1e9f, -5.0f, std::numeric_limits<float>::quiet_NaN()};
  float back[3];
  unpack_b10g11r11(pack_b10g11r11(big), back);
  EXPECT_FLOAT_EQ(back[0], 65024.0f);
  EXPECT_EQ(back[1], 0.0f);
  EXPECT_EQ(back[2], 0.0f);
  unpack_e5b9g9r9(pack_e5b9g9r9(big), back);
  EXPECT_FLOAT_EQ(back[0], 65408.0f);
}

TEST_F(Containers, Ktx2ReadBackGivesTheWrittenTexels) {
  const int n = 4;
  const std::vector<Image> levels = direction_cube(n);
  for (GpuFormat format : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9}) {
    SCOPED_TRACE(gpu_format_name(format));
    const fs::path file = dir_ / ("back_" + gpu_format_name(format) + ".ktx2");
    Ktx2Options o;
    o.format = format;
    o.key_values["envkit:ibl_roughness"] = "0,0.5,1";
    write_ktx2(file.string(), pointers(levels), o);
    const Ktx2Texels back = read_ktx2(file.string());
    EXPECT_EQ(back.format, format);
    EXPECT_EQ(back.faces, 6);
    EXPECT_EQ(back.key_values.at("envkit:ibl_roughness"), "0,0.5,1");
    ASSERT_EQ(back.levels.size(), levels.size());
    const double tol = format == GpuFormat::Rgba32f     ? 0.0
                       : format == GpuFormat::Rgba16f   ? 2e-3
                       : format == GpuFormat::B10G11R11 ? 2.0 / 32
                                                        : 2.0 / 256;
    for (std::size_t m = 0; m < levels.size(); ++m) {
      ASSERT_EQ(back.levels[m].width, levels[m].width);
      ASSERT_EQ(back.levels[m].height, levels[m].height);
      for (int y = 0; y < levels[m].height; ++y)
        for (int x = 0; x < levels[m].width; ++x) {
          for (int c = 0; c < 3; ++c) ASSERT_NEAR(back.levels[m].at(x, y, c), levels[m].at(x, y, c), tol) << m;
          EXPECT_EQ(back.levels[m].at(x, y, 3), 1.0f);
        }
    }
  }
  // A truncated file is refused with its name.
  const std::string whole = test::read_text(dir_ / "back_rgba32f.ktx2");
  std::ofstream(dir_ / "short.ktx2", std::ios::binary) << whole.substr(0, whole.size() - 16);
  try {
    read_ktx2((dir_ / "short.ktx2").string());
    ADD_FAILURE() << "a truncated KTX2 file was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("short.ktx2"), std::string::npos) << e.what();
  }
}

// A 4 x 24 cube strip (RGB) whose texels hold ordinary radiance, except for a few values no range-limited format
// holds: a sun of 1e6 in red, 7e4 in green, 65100 in blue (above rg11b10f's blue maximum 64512 only), negatives.
Image strip_with_sun() {
  Image level(4, 24, 3);
  std::fill(level.pixels.begin(), level.pixels.end(), 0.5f);
  level.at(1, 2, 0) = 1e6f;
  level.at(2, 2, 1) = 7e4f;
  level.at(3, 5, 2) = 65100.0f;
  level.at(0, 7, 0) = -2.0f;
  level.at(0, 8, 1) = -0.25f;
  return level;
}

TEST_F(Containers, WritersReportTheValuesTheirFormatClamps) {
  std::vector<Image> levels = {strip_with_sun(), Image(2, 12, 3), Image(1, 6, 3)};
  std::fill(levels[1].pixels.begin(), levels[1].pixels.end(), 1.0f);
  std::fill(levels[2].pixels.begin(), levels[2].pixels.end(), 1.0f);
  levels[1].at(0, 0, 2) = 2e5f;  // a second level's sun counts too
  struct Expected {
    GpuFormat format;
    std::size_t above, negative;
    double largest, lowest;
  };
  const Expected expected[] = {{GpuFormat::Rgba16f, 3, 0, 1e6, 0.0},
                               {GpuFormat::Rgba32f, 0, 0, 0.0, 0.0},
                               {GpuFormat::B10G11R11, 4, 2, 1e6, -2.0},
                               {GpuFormat::E5B9G9R9, 3, 2, 1e6, -2.0}};
  for (const Expected& e : expected) {
    SCOPED_TRACE(gpu_format_name(e.format));
    Ktx2Options ko;
    ko.format = e.format;
    DdsOptions dopt;
    dopt.format = e.format;
    const fs::path k = dir_ / ("sun_" + gpu_format_name(e.format) + ".ktx2");
    const fs::path d = dir_ / ("sun_" + gpu_format_name(e.format) + ".dds");
    for (const ClampReport& r :
         {write_ktx2(k.string(), pointers(levels), ko), write_dds(d.string(), pointers(levels), dopt)}) {
      EXPECT_EQ(r.above, e.above);
      EXPECT_EQ(r.negative, e.negative);
      EXPECT_EQ(r.largest, e.largest);
      EXPECT_EQ(r.lowest, e.lowest);
      EXPECT_EQ(r.any(), e.above + e.negative > 0);
      if (r.any()) {
        EXPECT_EQ(r.format, gpu_format_name(e.format));
      }
    }
  }
  // The line a tool prints.
  Ktx2Options ko;
  ko.format = GpuFormat::B10G11R11;
  const ClampReport r = write_ktx2((dir_ / "line.ktx2").string(), pointers(levels), ko);
  EXPECT_EQ(r.message("out.ktx2"),
            "out.ktx2: 4 values above rg11b10f's largest 65024 (64512 in blue) were clamped (largest 1e+06) and 2 "
            "negative values of the unsigned rg11b10f were stored as 0 (lowest -2); use a float output to keep the "
            "sun");
  EXPECT_EQ(ClampReport{}.message("out.ktx2"), "");
}

TEST_F(Containers, HalfExrCubeMipsClampsTheSunAndReportsIt) {
  Image level(4, 24, 3);
  std::fill(level.pixels.begin(), level.pixels.end(), 0.5f);
  level.at(1, 2, 0) = 1e6f;
  ExrCubeMipsOptions o;
  o.half = true;
  const fs::path file = dir_ / "sun_mips.exr";
  const ClampReport r = write_exr_cube_mips(file.string(), {&level}, o);
  // Level 0's sun, and level 1's 2 x 2 box average of it (250000.375); level 2's (62500.47) fits.
  EXPECT_EQ(r.above, 2u);
  EXPECT_EQ(r.largest, 1e6);
  EXPECT_EQ(r.format, "half");
  // Stored as half's largest, never as Inf (which a reader refuses).
  const Image back = read_image(file.string());
  EXPECT_EQ(back.at(1, 2, 0), 65504.0f);
  o.half = false;
  EXPECT_FALSE(write_exr_cube_mips((dir_ / "sun_mips_float.exr").string(), {&level}, o).any());
}

TEST_F(Containers, WritersRefuseInconsistentLevels) {
  std::vector<Image> levels = direction_cube(4);
  levels[1] = levels[2];
  EXPECT_THROW(write_ktx2((dir_ / "bad.ktx2").string(), pointers(levels), {}), Error);
  EXPECT_THROW(write_dds((dir_ / "bad.dds").string(), pointers(levels), {}), Error);
  EXPECT_FALSE(fs::exists(dir_ / "bad.ktx2"));
  EXPECT_FALSE(fs::exists(dir_ / "bad.dds"));
}

}  // namespace
