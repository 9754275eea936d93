// ConversionRequest: validate() refuses every combination that does not go together, naming the field at fault,
// and convert() resamples as the request says.
#include <envkit/envmap/conversion.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <string>

using namespace envkit;
using Field = ConversionField;

namespace {

ConversionRequest to(Kind kind) {
  ConversionRequest r;
  r.to = kind;
  return r;
}

/// The field validate() names for `r`, or nothing when it accepts it.
std::optional<Field> refused_field(const ConversionRequest& r) {
  try {
    validate(r);
  } catch (const ConversionError& e) {
    EXPECT_EQ(std::string(e.what()), std::string(conversion_field_name(e.field)) + ": " + e.message);
    return e.field;
  }
  return std::nullopt;
}

EnvMap small_sky() {
  EnvMap m;
  m.param = std::make_unique<LatLongMap>(16, 8);
  m.image = Image(16, 8, 3);
  for (std::size_t i = 0; i < m.image.pixels.size(); ++i) m.image.pixels[i] = float(i % 7) + 0.5f;
  m.image.metadata["envkit:source"] = "elsewhere.exr";
  m.image.metadata["note"] = "kept";
  return m;
}

}  // namespace

TEST(ConversionRequest, ALayoutAppliesToCubesOnly) {
  ConversionRequest r = to(Kind::LatLong);
  r.layout = CubeLayout::HorizontalCross;
  EXPECT_EQ(refused_field(r), Field::Layout);
  r.to = Kind::CubeMap;
  EXPECT_EQ(refused_field(r), std::nullopt);
}

TEST(ConversionRequest, SixFaceFilesAreACubeInAVerticalStrip) {
  ConversionRequest r = to(Kind::LatLong);
  r.output = "faces_%.exr";
  EXPECT_EQ(refused_field(r), Field::Output);
  r.to = Kind::CubeMap;
  EXPECT_EQ(refused_field(r), std::nullopt);
  r.layout = CubeLayout::HorizontalCross;
  EXPECT_EQ(refused_field(r), Field::Layout);
  r.layout = CubeLayout::VerticalStrip;
  EXPECT_EQ(refused_field(r), std::nullopt);
}

TEST(ConversionRequest, HalfFloatsNeedAnOpenExrOutput) {
  ConversionRequest r = to(Kind::LatLong);
  r.pixel_type = PixelType::Half;
  r.output = "sky.hdr";
  EXPECT_EQ(refused_field(r), Field::PixelType);
  r.output = "";  // in memory: no file format to refuse it
  EXPECT_EQ(refused_field(r), Field::PixelType);
  r.output = "sky.EXR";
  EXPECT_EQ(refused_field(r), std::nullopt);
}

TEST(ConversionRequest, ACompressionTheFormatTakes) {
  ConversionRequest r = to(Kind::LatLong);
  r.compression = "zip";
  r.output = "sky.png";
  EXPECT_EQ(refused_field(r), Field::Compression);
  r.output = "sky.tif";
  EXPECT_EQ(refused_field(r), std::nullopt);
  r.output = "sky.exr";
  EXPECT_EQ(refused_field(r), std::nullopt);
  r.compression = "bogus";
  EXPECT_EQ(refused_field(r), Field::Compression);
}

TEST(ConversionRequest, ViewFieldsApplyToCameraViewsOnly) {
  ConversionRequest r = to(Kind::LatLong);
  r.view = ViewParams{};
  EXPECT_EQ(refused_field(r), Field::View);
  r.view.reset();
  r.aspect = 1.5;
  EXPECT_EQ(refused_field(r), Field::Aspect);
  r.aspect.reset();
  r.height = 32;
  EXPECT_EQ(refused_field(r), Field::Height);
  for (Kind kind : {Kind::Perspective, Kind::Fisheye}) {
    r = to(kind);
    r.view = ViewParams{};
    r.view->fov_degrees = 60.0;
    r.aspect = 1.5;
    EXPECT_EQ(refused_field(r), std::nullopt);
    r.height = 32;  // a height and an aspect say the same thing twice
    EXPECT_EQ(refused_field(r), Field::Height);
  }
}

TEST(ConversionRequest, AViewOutOfItsLensRange) {
  ConversionRequest r = to(Kind::Perspective);
  r.view = ViewParams{};
  r.view->fov_degrees = 200.0;
  EXPECT_EQ(refused_field(r), Field::View);
  r.to = Kind::Fisheye;
  EXPECT_EQ(refused_field(r), std::nullopt);
  r.view->fov_degrees = 1e-9;
  EXPECT_EQ(refused_field(r), Field::View);
}

TEST(ConversionRequest, AnOutputTooLargeIsRefusedWithItsSize) {
  ConversionRequest r = to(Kind::CubeMap);
  r.size = 1 << 17;
  try {
    validate(r);
    FAIL() << "a cube of 131072 x 786432 texels was accepted";
  } catch (const ConversionError& e) {
    EXPECT_EQ(e.field, Field::Size);
    EXPECT_EQ(e.value, "131072");
    EXPECT_NE(e.message.find("cube output of 131072 x 786432"), std::string::npos) << e.message;
  }
  r.size = 64;
  EXPECT_EQ(refused_field(r), std::nullopt);
}

TEST(ConversionRequest, ConvertResamplesOntoTheRequestedMap) {
  const EnvMap sky = small_sky();
  ConversionRequest r = to(Kind::CubeMap);
  r.size = 4;
  r.convention = &convention("gl");
  r.filter = Filter::Bilinear;
  validate(r);
  const EnvMap cube = convert(sky, r);
  EXPECT_EQ(cube.param->kind(), Kind::CubeMap);
  EXPECT_EQ(cube.convention, "gl");
  // The same pixels as resampling by hand onto the spec the request describes.
  EnvMap by_hand;
  by_hand.convention = "gl";
  by_hand.param = make_parameterization(spec_for(Kind::CubeMap, 4, convention("gl")));
  ResampleOptions ro;
  ro.filter = Filter::Bilinear;
  const Image expected = resample(sky.ref(), *by_hand.param, by_hand.to_world(), ro);
  EXPECT_EQ(cube.image.pixels, expected.pixels);
  // The source's envkit:* keys describe another file; the others stay.
  EXPECT_EQ(cube.image.metadata.count("envkit:source"), 0u);
  EXPECT_EQ(cube.image.metadata.count("note"), 1u);
  // Without a convention of its own the output keeps the source's.
  r.convention = nullptr;
  EXPECT_EQ(convert(sky, r).convention, "envkit");
}

TEST(ConversionRequest, ARotationTurnsWhatTheOutputShows) {
  const EnvMap sky = small_sky();
  ConversionRequest r = to(Kind::LatLong);
  r.size = 8;
  r.filter = Filter::Nearest;
  const EnvMap plain = convert(sky, r);
  r.rotation = Mat3(-1, 0, 0, 0, 1, 0, 0, 0, -1);  // half a turn about +Y: a lat-long shifts by half its width
  const EnvMap turned = convert(sky, r);
  EXPECT_NE(plain.image.pixels, turned.image.pixels);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(turned.image.at(x, y)[c], plain.image.at((x + 8) % 16, y)[c]) << x << "," << y;
}
