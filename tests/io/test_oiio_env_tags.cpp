// OpenImageIO's environment tags (oiio_env_tags.h): read as OIIO's texture
// system reads them (src/libtexture/environment.cpp: TextureFile setup and
// vector_to_latlong), written with the types it reads (updirection string,
// sampleborder int, as maketx sets them).
#include <OpenImageIO/imageio.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/io/oiio_env_tags.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

using namespace envkit;
namespace fs = std::filesystem;

namespace {

class OiioEnvTagsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("envkit_oiiotags_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

// A W x H lat-long whose texel (i, j) holds i + W j, tagged with OIIO's
// environment tags and nothing else. OIIO 2.4's own writers drop these tags
// (its OpenEXR reader derives them from the envmap attribute instead), so the
// file is written by envkit; the test checks that OIIO reads the tags back
// with the values and types its texture system asks for.
void write_tagged_exr(const std::string& file, int w, int h, const char* updirection, int sampleborder) {
  Image img(w, h, 3);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i)
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = float(i + w * j);
  WriteOptions opt;
  opt.metadata["oiio:updirection"] = updirection;
  opt.metadata["oiio:sampleborder"] = std::to_string(sampleborder);
  write_image(file, img, opt);
  auto in = OIIO::ImageInput::open(file);
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("oiio:updirection"), updirection);
  EXPECT_EQ(in->spec().get_int_attribute("oiio:sampleborder", -1), sampleborder);
}

Vec3 random_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double z = 2 * u(rng) - 1, phi = kTwoPi * u(rng), s = std::sqrt(1 - z * z);
  return Vec3(s * std::cos(phi), s * std::sin(phi), z);
}

}  // namespace

// OIIO: updirection "y" or "z" picks the orientation (its "latlong_up" default
// is "y"), a nonzero sampleborder puts edge texels on the poles and seam
// (s = i / (W - 1)). "y" with a border is exactly OpenEXR's corner grid.
TEST(OiioEnvTags, ReadsTheTagsAsOiioDoes) {
  struct Row {
    std::map<std::string, std::string> meta;
    std::string convention;
    std::optional<TexelGrid> grid;
  };
  const std::vector<Row> rows = {
      {{{"oiio:updirection", "y"}}, "envkit", std::nullopt},
      {{{"oiio:updirection", "y"}, {"oiio:sampleborder", "1"}}, "openexr", std::nullopt},
      {{{"oiio:updirection", "y"}, {"oiio:sampleborder", "0"}}, "envkit", std::nullopt},
      {{{"oiio:updirection", "z"}}, "renderman", std::nullopt},
      {{{"oiio:updirection", "z"}, {"oiio:sampleborder", "1"}}, "renderman", TexelGrid::Corner},
      {{{"oiio:sampleborder", "2"}}, "openexr", std::nullopt},
  };
  for (const Row& row : rows) {
    const auto r = read_oiio_env_tags(row.meta);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->convention, row.convention);
    EXPECT_EQ(r->grid, row.grid) << row.convention;
    EXPECT_FALSE(r->reason.empty());
  }
  EXPECT_FALSE(read_oiio_env_tags({}).has_value());
  EXPECT_FALSE(read_oiio_env_tags({{"oiio:updirection", "x"}}).has_value());
}

// Written only where they describe the map: updirection for lat-longs in
// envkit's frame ("y") or RenderMan's ("z"), sampleborder for centre or corner
// lat-longs and cubes.
TEST(OiioEnvTags, WrittenWhereTheyApply) {
  using Tags = std::map<std::string, std::string>;
  auto tags = [](const char* conv, Kind kind) {
    const Convention& c = convention(conv);
    const auto p = make_parameterization(spec_for(kind, 8, c));
    return oiio_env_tags_for(*p, c.frame(kind));
  };
  EXPECT_EQ(tags("envkit", Kind::LatLong), (Tags{{"oiio:updirection", "y"}, {"oiio:sampleborder", "0"}}));
  EXPECT_EQ(tags("openexr", Kind::LatLong), (Tags{{"oiio:updirection", "y"}, {"oiio:sampleborder", "1"}}));
  EXPECT_EQ(tags("renderman", Kind::LatLong), (Tags{{"oiio:updirection", "z"}, {"oiio:sampleborder", "0"}}));
  EXPECT_EQ(tags("unity", Kind::LatLong), (Tags{{"oiio:sampleborder", "0"}}));
  EXPECT_EQ(tags("mitsuba", Kind::LatLong), (Tags{{"oiio:updirection", "y"}}));
  EXPECT_EQ(tags("openexr", Kind::CubeMap), (Tags{{"oiio:sampleborder", "1"}}));
  EXPECT_EQ(tags("gl", Kind::CubeMap), (Tags{{"oiio:sampleborder", "0"}}));
  EXPECT_TRUE(tags("pbrt", Kind::Octahedral).empty());
  // A rotated envkit map is in neither frame.
  const LatLongMap ll(16, 8);
  EXPECT_EQ(oiio_env_tags_for(ll, rotation_from_euler_degrees(30, 0, 0)), (Tags{{"oiio:sampleborder", "0"}}));
}

// A file whose tags say RenderMan lat-long with a sample border reads as
// OIIO's texture system samples it: direction R (RenderMan frame) is at s = atan2(R.y, R.x)
// / 2 pi + 1/2, t = 1/2 - atan2(R.z, hypot(R.x, R.y)) / pi, and texel (i, j)
// sits at s = i / (W - 1), t = j / (H - 1).
TEST_F(OiioEnvTagsTest, TaggedFileReadsAsOiioSamplesIt) {
  const int w = 64, h = 32;
  const std::string file = path("tagged.exr");
  write_tagged_exr(file, w, h, "z", 1);
  Detection det;
  const EnvMap map = load_envmap(file, {}, &det);
  EXPECT_EQ(map.convention, "renderman");
  EXPECT_NE(det.convention_reason.find("oiio:updirection=z"), std::string::npos) << det.convention_reason;
  const auto* ll = dynamic_cast<const LatLongMap*>(map.param.get());
  ASSERT_NE(ll, nullptr);
  EXPECT_EQ(ll->grid(), TexelGrid::Corner);
  const Mat3 world_to_map = transposed(map.to_world());
  std::mt19937_64 rng(31);
  for (int k = 0; k < 5000; ++k) {
    const Vec3 e = random_direction(rng);
    const Vec3 r(e.x, e.z, e.y);
    const double s = std::atan2(r.y, r.x) / kTwoPi + 0.5, t = 0.5 - std::atan2(r.z, std::hypot(r.x, r.y)) / kPi;
    const Vec2 p = map.param->to_image(apply(world_to_map, e));
    const double dx = std::abs(p.x - (s * (w - 1) + 0.5));
    ASSERT_LT(std::min(dx, std::abs(dx - (w - 1))), 1e-6) << e;
    ASSERT_NEAR(p.y, t * (h - 1) + 0.5, 1e-6) << e;
  }
  // The texel centre (i, j) holds i + W j, as written.
  EXPECT_EQ(map.image.at(5, 3, 0), float(5 + w * 3));
}

// envkit's own metadata is more specific than OIIO's tags and wins.
TEST_F(OiioEnvTagsTest, EnvkitMetadataWinsOverOiioTags) {
  const std::string file = path("both.exr");
  const Image img(16, 8, 3);
  WriteOptions w;
  w.metadata["envkit:convention"] = "blender";
  w.metadata["oiio:updirection"] = "z";
  write_image(file, img, w);
  EXPECT_EQ(load_envmap(file).convention, "blender");
}

// save_envmap writes the tags with the types OIIO reads: updirection a string,
// sampleborder an int.
TEST_F(OiioEnvTagsTest, SavedMapsCarryTypedTags) {
  auto save = [&](const char* conv, Kind kind, const std::string& name) {
    EnvMap map;
    map.convention = conv;
    map.param = make_parameterization(spec_for(kind, 8, convention(conv)));
    map.image = Image(map.param->width(), map.param->height(), 3);
    save_envmap(path(name), map);
    auto in = OIIO::ImageInput::open(path(name));
    EXPECT_TRUE(in);
    return in ? in->spec() : OIIO::ImageSpec();
  };
  const OIIO::ImageSpec rman = save("renderman", Kind::LatLong, "rman.exr");
  EXPECT_EQ(rman.get_string_attribute("oiio:updirection"), "z");
  const OIIO::ParamValue* border = rman.find_attribute("oiio:sampleborder");
  ASSERT_NE(border, nullptr);
  EXPECT_EQ(border->type(), OIIO::TypeDesc::INT);
  EXPECT_EQ(rman.get_int_attribute("oiio:sampleborder", -1), 0);
  EXPECT_EQ(load_envmap(path("rman.exr")).convention, "renderman");

  const OIIO::ImageSpec cube = save("gl", Kind::CubeMap, "cube.exr");
  EXPECT_EQ(cube.get_string_attribute("oiio:updirection"), "");
  EXPECT_EQ(cube.get_int_attribute("oiio:sampleborder", -1), 0);

  const OIIO::ImageSpec oct = save("pbrt", Kind::Octahedral, "oct.exr");
  EXPECT_EQ(oct.find_attribute("oiio:sampleborder"), nullptr);
}
