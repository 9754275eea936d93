// The single mip-mapped OpenEXR cube (exr_cube_mips.h, envprefilter -o name.exr) read back by OpenEXR itself and by
// OpenImageIO. Known directions on known texels: every texel of every face of every level holds 1 + the direction
// OpenEXR's own Imf::CubeMap gives it (pixelPosition and direction of each face position, in that level's data window).
#include <OpenEXR/ImfArray.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmap.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTiledInputFile.h>
#include <OpenImageIO/imageio.h>
#include <envkit/core/error.h>
#include <envkit/ibl/exr_cube_mips.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;
namespace fs = std::filesystem;

namespace {

Vec3 encode(const Vec3& d) { return Vec3(1.0) + d; }

// The cube's own chain (face size n, n/2, ... 1) in OpenEXR's faces and corner grid, texels 1 + direction.
std::vector<Image> direction_chain(int n) {
  std::vector<Image> levels;
  for (int s = n; s >= 1; s /= 2)
    levels.push_back(rasterize(CubeMap(s, CubeLayout::VerticalStrip, CubeBasis::Envkit, TexelGrid::Corner), encode));
  return levels;
}

std::vector<const Image*> pointers(const std::vector<Image>& levels) {
  std::vector<const Image*> p;
  for (const Image& l : levels) p.push_back(&l);
  return p;
}

// Level l of a tiled file as RGB floats, rows of the level's data window.
std::vector<float> read_level(Imf::TiledInputFile& in, int l) {
  const Imath::Box2i dw = in.dataWindowForLevel(l);
  const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  std::vector<float> px(std::size_t(w) * h * 3);
  Imf::FrameBuffer frame;
  const char* names[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c)
    frame.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data() + c), 12, 12 * std::size_t(w)));
  in.setFrameBuffer(frame);
  in.readTiles(0, in.numXTiles(l) - 1, 0, in.numYTiles(l) - 1, l);
  return px;
}

class ExrCube : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_exr_cube_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ExrCube, OpenExrReadsKnownDirectionsOnEveryLevel) {
  for (int n : {8, 6}) {  // a power of two, and a size whose levels have padding rows
    SCOPED_TRACE("face size " + std::to_string(n));
    const std::vector<Image> chain = direction_chain(n);
    const fs::path file = dir_ / ("cube" + std::to_string(n) + ".exr");
    ExrCubeMipsOptions o;
    o.tile = 4;  // several tiles per level
    o.attributes["envkit:ibl_roughness"] = "0,0.5,1";
    write_exr_cube_mips(file.string(), pointers(chain), o);

    Imf::TiledInputFile in(file.string().c_str());
    const Imf::Header& h = in.header();
    ASSERT_TRUE(Imf::hasEnvmap(h));
    EXPECT_EQ(Imf::envmap(h), Imf::ENVMAP_CUBE);
    EXPECT_EQ(in.levelMode(), Imf::MIPMAP_LEVELS);
    EXPECT_EQ(in.levelRoundingMode(), Imf::ROUND_DOWN);
    EXPECT_EQ(in.numLevels(), exr_cube_mip_levels(n));
    EXPECT_EQ(in.numLevels(), 6);  // floor(log2(6N)) + 1 for 48 and 36 texels high
    EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("envkit:ibl_roughness").value(), "0,0.5,1");
    EXPECT_EQ(h.typedAttribute<Imf::StringAttribute>("envkit:ibl_levels").value(), std::to_string(chain.size()));

    for (int l = 0; l < in.numLevels(); ++l) {
      const Imath::Box2i dw = in.dataWindowForLevel(l);
      const int w = dw.max.x + 1, hgt = dw.max.y + 1;
      const std::vector<float> px = read_level(in, l);
      const int face = Imf::CubeMap::sizeOfFace(dw);
      if (l < int(chain.size())) {
        ASSERT_EQ(face, std::max(1, n >> l));
        // OpenEXR's face coordinates (u, v) in [0, s - 1]^2: pixelPosition places them in the level, direction
        // gives what they see.
        for (int f = 0; f < 6; ++f)
          for (int v = 0; v < face; ++v)
            for (int u = 0; u < face; ++u) {
              const Imath::V2f pos{float(u), float(v)};
              const Imath::V2f p = Imf::CubeMap::pixelPosition(Imf::CubeMapFace(f), dw, pos);
              const Imath::V3f d = Imf::CubeMap::direction(Imf::CubeMapFace(f), dw, pos);
              const Vec3 want = encode(Vec3(d.x, d.y, d.z).normalized());
              const int x = int(std::lround(p.x)), y = int(std::lround(p.y));
              ASSERT_TRUE(x >= 0 && x < w && y >= f * face && y < (f + 1) * face) << "face " << f;
              const float* got = &px[(std::size_t(y) * w + x) * 3];
              EXPECT_NEAR(got[0], want.x, 1e-5) << "level " << l << " face " << f << " pixel " << x << "," << y;
              EXPECT_NEAR(got[1], want.y, 1e-5) << "level " << l << " face " << f << " pixel " << x << "," << y;
              EXPECT_NEAR(got[2], want.z, 1e-5) << "level " << l << " face " << f << " pixel " << x << "," << y;
            }
        // Rows past the six faces (sizes that are not powers of two) are padding.
        for (int y = 6 * face; y < hgt; ++y)
          for (int x = 0; x < w; ++x) EXPECT_EQ(px[(std::size_t(y) * w + x) * 3], 0.0f) << "level " << l;
      } else {
        // Past the cube's chain: no faces left (1 x 3 .. 1 x 1); the mean of the 1 x 1 faces' 1 + axis is 1.
        EXPECT_EQ(face, 0);
        for (float v : px) EXPECT_NEAR(v, 1.0f, 1e-6) << "level " << l;
      }
    }
  }
}

TEST_F(ExrCube, OiioReadsEveryMipLevel) {
  const int n = 8;
  const std::vector<Image> chain = direction_chain(n);
  const fs::path file = dir_ / "cube.exr";
  write_exr_cube_mips(file.string(), pointers(chain));
  Imf::TiledInputFile exr(file.string().c_str());

  auto in = OIIO::ImageInput::open(file.string());
  ASSERT_TRUE(in) << OIIO::geterror();
  int levels = 0;
  while (in->seek_subimage(0, levels)) {
    const OIIO::ImageSpec& spec = in->spec();
    const Imath::Box2i dw = exr.dataWindowForLevel(levels);
    EXPECT_EQ(spec.width, dw.max.x + 1) << "level " << levels;
    EXPECT_EQ(spec.height, dw.max.y + 1) << "level " << levels;
    std::vector<float> oiio(std::size_t(spec.width) * spec.height * 3);
    ASSERT_TRUE(in->read_image(0, levels, 0, 3, OIIO::TypeDesc::FLOAT, oiio.data())) << in->geterror();
    EXPECT_EQ(oiio, read_level(exr, levels)) << "level " << levels;
    ++levels;
  }
  EXPECT_EQ(levels, exr.numLevels());
  ASSERT_TRUE(in->seek_subimage(0, 0));
  EXPECT_EQ(in->spec().get_string_attribute("textureformat"), "CubeFace Environment");
}

TEST_F(ExrCube, WriterRefusesInconsistentLevels) {
  std::vector<Image> chain = direction_chain(8);
  chain[1] = chain[2];
  const fs::path file = dir_ / "bad.exr";
  EXPECT_THROW(write_exr_cube_mips(file.string(), pointers(chain)), Error);
  std::vector<Image> too_many = direction_chain(8);
  too_many.push_back(too_many.back());
  EXPECT_THROW(write_exr_cube_mips(file.string(), pointers(too_many)), Error);
}

// envprefilter -o name.exr: the chain prefiltered in OpenEXR's faces, bit for bit what prefilter_ggx computes.
TEST_F(ExrCube, EnvprefilterWritesTheChainInOneFile) {
  const EnvMap map = latlong_env(64, smooth_sky);
  const std::string input = (dir_ / "sky.exr").string(), out = (dir_ / "ggx.exr").string();
  write_image(input, map.image);
  test::CommandResult r =
      test::run_tool("envprefilter", {input, "-o", out, "--size", "8", "--levels", "3", "-q"}, dir_);
  ASSERT_EQ(r.code, 0) << r.err;

  PrefilterOptions po;
  po.size = 8;
  po.levels = 3;
  po.cube_basis = CubeBasis::Envkit;
  po.cube_grid = TexelGrid::Corner;
  const PrefilteredChain want = prefilter_ggx(map.ref(), po);

  Imf::TiledInputFile in(out.c_str());
  EXPECT_EQ(Imf::envmap(in.header()), Imf::ENVMAP_CUBE);
  EXPECT_EQ(in.numLevels(), 6);
  auto attr = [&](const char* key) { return in.header().typedAttribute<Imf::StringAttribute>(key).value(); };
  EXPECT_EQ(attr("envkit:ibl_levels"), "3");
  EXPECT_EQ(attr("envkit:ibl_roughness"), "0,0.5,1");
  EXPECT_EQ(attr("envkit:ibl_roughness_mapping"), "gltf");
  EXPECT_EQ(attr("envkit:convention"), "openexr");
  for (int l = 0; l < 3; ++l) {
    const std::vector<float> px = read_level(in, l);
    const Image& w = want.levels[l].image;
    ASSERT_EQ(px.size(), std::size_t(w.width) * w.height * 3);
    for (int y = 0; y < w.height; ++y)
      for (int x = 0; x < w.width; ++x)
        for (int c = 0; c < 3; ++c)
          ASSERT_FLOAT_EQ(px[(std::size_t(y) * w.width + x) * 3 + c], w.at(x, y, c)) << l << " " << x << "," << y;
  }
  // Level 3 (face size 1) is past the 3 prefiltered levels: each face the mean of the 2 x 2 texels of level 2's face.
  const std::vector<float> tail = read_level(in, 3);
  const Image& last = want.levels[2].image;
  for (int f = 0; f < 6; ++f)
    for (int c = 0; c < 3; ++c) {
      const double mean =
          (double(last.at(0, 2 * f, c)) + last.at(1, 2 * f, c) + last.at(0, 2 * f + 1, c) + last.at(1, 2 * f + 1, c)) /
          4.0;
      EXPECT_NEAR(tail[std::size_t(f) * 3 + c], mean, 1e-6 * std::abs(mean)) << "face " << f;
    }
  // Level 0 read as a map is the OpenEXR cube convention (the envmap attribute and envkit:convention agree).
  r = test::run_tool("envinfo", {out, "--json"}, dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json info = nlohmann::json::parse(r.out);
  EXPECT_NE(info.dump().find("openexr"), std::string::npos) << info.dump();
  EXPECT_EQ(info["levels"]["mode"], "mipmap") << info.dump();
  EXPECT_EQ(info["levels"]["sizes"].size(), 6u);
  EXPECT_EQ(info["levels"]["sizes"][1][1], 24);
  EXPECT_EQ(info["ggx_chain"]["prefiltered_levels"], "3");

  // One mip-mapped EXR holds a cube only: an octahedral chain is a usage error, with no output.
  const std::string octa = (dir_ / "octa.exr").string();
  r = test::run_tool("envprefilter", {input, "-o", octa, "--octahedral", "--size", "8", "-q"}, dir_);
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(fs::exists(octa));
}

}  // namespace
