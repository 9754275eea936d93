// envkit reads and writes PNG with libpng itself (libenv/io/src/image_io_png.cpp) instead of loading the OpenImageIO
// module. These tests hold it to OIIO's PNG reader and writer, the independent implementation it replaces: the same
// header as image_io.cpp sees it and the same pixels, bit for bit, on every kind of PNG libpng can write.
#include <OpenImageIO/imageio.h>
#include <envkit/core/error.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/src/image_backend.h"

namespace fs = std::filesystem;
using envkit::Image;
using envkit::detail::FileSpec;

namespace {

struct TempDir {
  fs::path dir;
  TempDir() {
    dir = fs::temp_directory_path() / ("envkit_png_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  ~TempDir() { fs::remove_all(dir); }
  std::string operator()(const std::string& name) const { return (dir / name).string(); }
};

/// One PNG layout to write with libpng's own API.
struct Layout {
  const char* name;
  int color_type;
  int bit_depth;
  bool interlace = false;
  bool trns = false;   // a tRNS chunk (palette alpha, or a transparent gray/RGB key)
  double gamma = 0.0;  // > 0: a gAMA chunk with this value
  bool srgb = false;   // an sRGB chunk
  bool text = false;   // tEXt chunks, one under a name OIIO renames
};

int channels_in_file(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY:
      return 1;
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return 2;
    case PNG_COLOR_TYPE_RGB:
      return 3;
    case PNG_COLOR_TYPE_RGB_ALPHA:
      return 4;
    default:
      return 1;  // palette: one index per pixel
  }
}

/// Writes a 37 x 23 image of `layout` whose samples run through every code value of the bit depth.
void write_layout(const std::string& path, const Layout& layout) {
  const int w = 37, h = 23, depth = layout.bit_depth, nc = channels_in_file(layout.color_type);
  const int max_value = (1 << depth) - 1;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  // No setjmp: a libpng error here aborts the test binary through libpng's default handler, which is a failure.
  png_init_io(png, f);
  png_set_IHDR(png, info, w, h, depth, layout.color_type, layout.interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  std::vector<png_color> palette;
  std::vector<png_byte> palette_alpha;
  if (layout.color_type == PNG_COLOR_TYPE_PALETTE) {
    for (int i = 0; i <= max_value; ++i)
      palette.push_back({png_byte(i * 37 % 256), png_byte(255 - i * 11 % 256), png_byte(i * 5 % 256)});
    png_set_PLTE(png, info, palette.data(), static_cast<int>(palette.size()));
    if (layout.trns) {
      for (int i = 0; i <= max_value; ++i) palette_alpha.push_back(png_byte(i * 53 % 256));
      png_set_tRNS(png, info, palette_alpha.data(), static_cast<int>(palette_alpha.size()), nullptr);
    }
  } else if (layout.trns) {
    png_color_16 key{};
    key.gray = key.red = key.green = key.blue = png_uint_16(max_value / 3);
    png_set_tRNS(png, info, nullptr, 0, &key);
  }
  if (layout.srgb) png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  if (layout.gamma > 0.0) png_set_gAMA(png, info, layout.gamma);
  png_text text[2] = {};
  char k0[] = "Description", v0[] = "a probe", k1[] = "envkit:parameterization", v1[] = "latlong";
  text[0].compression = text[1].compression = PNG_TEXT_COMPRESSION_NONE;
  text[0].key = k0, text[0].text = v0, text[1].key = k1, text[1].text = v1;
  if (layout.text) png_set_text(png, info, text, 2);
  png_write_info(png, info);
  if (depth < 8) png_set_packing(png);
  if (depth == 16) png_set_swap(png);
  const int bytes = depth == 16 ? 2 : 1;
  std::vector<png_byte> row(std::size_t(w * nc * bytes));
  const int passes = png_set_interlace_handling(png);
  for (int pass = 0; pass < passes; ++pass)
    for (int y = 0; y < h; ++y) {
      for (int i = 0; i < w * nc; ++i) {
        const int v = (y * w * nc + i) * 7919 % (max_value + 1);  // a stride coprime to every range: all values
        if (bytes == 2) {
          reinterpret_cast<png_uint_16*>(row.data())[i] = png_uint_16(v);
        } else {
          row[std::size_t(i)] = png_byte(v);
        }
      }
      png_write_row(png, row.data());
    }
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  std::fclose(f);
}

struct OiioRead {
  OIIO::ImageSpec spec;
  std::vector<float> pixels;
};

OiioRead read_with_oiio(const std::string& path) {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);  // as libenv's OIIO module opens files
  auto in = OIIO::ImageInput::open(path, &config);
  EXPECT_TRUE(in) << OIIO::geterror();
  OiioRead r;
  if (!in) return r;
  r.spec = in->spec();
  r.pixels.resize(std::size_t(r.spec.width) * r.spec.height * r.spec.nchannels);
  EXPECT_TRUE(in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::FLOAT, r.pixels.data()));
  return r;
}

}  // namespace

TEST(PngCodec, ReadsEveryLayoutAsOpenImageIODoes) {
  TempDir tmp;
  const Layout layouts[] = {
      {"gray1", PNG_COLOR_TYPE_GRAY, 1},
      {"gray2", PNG_COLOR_TYPE_GRAY, 2},
      {"gray4_gamma1", PNG_COLOR_TYPE_GRAY, 4, false, false, 1.0},
      {"gray8_trns", PNG_COLOR_TYPE_GRAY, 8, false, true},
      {"gray16", PNG_COLOR_TYPE_GRAY, 16},
      {"graya8", PNG_COLOR_TYPE_GRAY_ALPHA, 8, false, false, 0.0, false, true},
      {"graya16_interlaced", PNG_COLOR_TYPE_GRAY_ALPHA, 16, true},
      {"rgb8_srgb", PNG_COLOR_TYPE_RGB, 8, false, false, 0.0, true},
      {"rgb8_gamma22_text", PNG_COLOR_TYPE_RGB, 8, false, false, 1.0 / 2.2, false, true},
      {"rgb16_trns", PNG_COLOR_TYPE_RGB, 16, false, true},
      {"rgb8_gamma18", PNG_COLOR_TYPE_RGB, 8, false, false, 1.0 / 1.8},
      {"rgb8_gamma2", PNG_COLOR_TYPE_RGB, 8, false, false, 0.5},
      {"rgba8_interlaced", PNG_COLOR_TYPE_RGB_ALPHA, 8, true},
      {"rgba16_srgb", PNG_COLOR_TYPE_RGB_ALPHA, 16, false, false, 0.0, true},
      {"palette1", PNG_COLOR_TYPE_PALETTE, 1},
      {"palette4_trns", PNG_COLOR_TYPE_PALETTE, 4, false, true},
      {"palette8_trns_interlaced", PNG_COLOR_TYPE_PALETTE, 8, true, true},
  };
  for (const Layout& layout : layouts) {
    SCOPED_TRACE(layout.name);
    const std::string path = tmp(std::string(layout.name) + ".png");
    write_layout(path, layout);
    ASSERT_TRUE(envkit::detail::is_png_file(path));

    std::string error;
    bool unknown = true;
    auto in = envkit::detail::png_backend().open(path, error, unknown);
    ASSERT_TRUE(in) << error;
    const FileSpec& ours = in->spec();
    std::vector<float> pixels(std::size_t(ours.width) * ours.height * ours.nchannels);
    ASSERT_EQ(in->read(pixels.data()), "");

    const OiioRead theirs = read_with_oiio(path);
    EXPECT_EQ(ours.format, "png");
    EXPECT_EQ(ours.pixel_type, theirs.spec.format.c_str());
    EXPECT_EQ(ours.format_bytes, int(theirs.spec.format.size()));
    EXPECT_EQ(ours.width, theirs.spec.width);
    EXPECT_EQ(ours.height, theirs.spec.height);
    ASSERT_EQ(ours.nchannels, theirs.spec.nchannels);
    EXPECT_EQ(ours.channel_names, theirs.spec.channelnames);
    EXPECT_EQ(ours.alpha_channel, theirs.spec.alpha_channel);
    EXPECT_EQ(ours.colorspace_tag, theirs.spec.get_string_attribute("oiio:ColorSpace"));
    if (layout.gamma > 0.0 && !layout.srgb) {
      EXPECT_FLOAT_EQ(ours.gamma, theirs.spec.get_float_attribute("oiio:Gamma"));
    }
    EXPECT_EQ(ours.unassociated_alpha, theirs.spec.get_int_attribute("oiio:UnassociatedAlpha") != 0);
    if (layout.text) {
      EXPECT_EQ(ours.metadata.at("ImageDescription"), theirs.spec.get_string_attribute("ImageDescription"));
      EXPECT_EQ(ours.metadata.at("envkit:parameterization"), "latlong");
      EXPECT_EQ(theirs.spec.get_string_attribute("envkit:parameterization"), "latlong");
    }
    ASSERT_EQ(pixels.size(), theirs.pixels.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      if (pixels[i] != theirs.pixels[i] && differing < 3)
        ADD_FAILURE() << "sample " << i << ": " << pixels[i] << " vs " << theirs.pixels[i];
      differing += pixels[i] != theirs.pixels[i];
    }
    EXPECT_EQ(differing, 0u) << "of " << pixels.size() << " samples";
  }
}

TEST(PngCodec, WritesWhatOpenImageIOWrites) {
  // Every code value of 8 and 16 bits, plus the half-way points between neighbours (the rounding), written by the
  // libpng backend and by OIIO's writer from the same floats: OIIO must read the same integers and tags from both.
  TempDir tmp;
  for (const char* type : {"uint8", "uint16"}) {
    SCOPED_TRACE(type);
    const int levels = std::string(type) == "uint8" ? 256 : 65536;
    envkit::detail::WriteSpec spec;
    spec.width = 512;
    spec.height = levels * 2 / spec.width + 1;
    spec.channels = 4;
    spec.pixel_type = type;
    spec.channel_names = {"R", "G", "B", "A"};
    spec.alpha_channel = 3;
    spec.unassociated_alpha = true;
    spec.attributes = {{"oiio:ColorSpace", "sRGB"},
                       {"ImageDescription", "ramp"},
                       {"Artist", "envkit tests"},
                       {"envkit:convention", "envkit"},
                       {"Software", "envkit"}};
    std::vector<float> pixels(std::size_t(spec.width) * spec.height * 4);
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      const double code = double(i % std::size_t(2 * levels)) / 2.0;  // k and k + 1/2
      pixels[i] = std::min(1.0f, float(code / (levels - 1)));
    }
    const std::string ours = tmp(std::string("ours_") + type + ".png");
    const std::string theirs = tmp(std::string("theirs_") + type + ".png");
    ASSERT_EQ(envkit::detail::png_backend().write(ours, spec, pixels.data()), "");
    ASSERT_EQ(envkit::detail::oiio_backend(theirs).write(theirs, spec, pixels.data()), "");
    const OiioRead a = read_with_oiio(ours), b = read_with_oiio(theirs);
    EXPECT_EQ(a.spec.format, b.spec.format);
    EXPECT_EQ(a.spec.nchannels, 4);
    EXPECT_EQ(a.spec.get_string_attribute("oiio:ColorSpace"), "sRGB");
    EXPECT_EQ(a.spec.get_string_attribute("ImageDescription"), "ramp");
    EXPECT_EQ(a.spec.get_string_attribute("Artist"), "envkit tests");
    EXPECT_EQ(a.spec.get_string_attribute("envkit:convention"), "envkit");
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    std::size_t differing = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) differing += a.pixels[i] != b.pixels[i];
    EXPECT_EQ(differing, 0u);
  }
}

TEST(PngCodec, SixteenBitRoundTripThroughTheImageApi) {
  // write_image encodes linear light to sRGB in 16 bits and read_image decodes it: within the 16-bit step.
  // (test_hdr_io checks that PNG runs never load the OIIO module.)
  TempDir tmp;
  const std::string path = tmp("rt.png");
  Image img;
  img.width = 8;
  img.height = 4;
  img.channels = 3;
  img.channel_names = {"R", "G", "B"};
  img.pixels.resize(8 * 4 * 3);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float(i) / float(img.pixels.size());
  envkit::WriteOptions options;
  options.pixel_type = envkit::PixelType::UInt16;
  envkit::write_image(path, img, options);
  envkit::ReadReport report;
  const Image back = envkit::read_image(path, {}, &report);
  EXPECT_EQ(report.format, "png");
  EXPECT_EQ(report.pixel_type, "uint16");
  ASSERT_EQ(back.pixels.size(), img.pixels.size());
  for (std::size_t i = 0; i < img.pixels.size(); ++i) EXPECT_NEAR(back.pixels[i], img.pixels[i], 2e-5f) << i;
}

TEST(PngCodec, DamagedFilesGiveOneErrorNamingTheFile) {
  TempDir tmp;
  const std::string good = tmp("good.png");
  write_layout(good, {"rgb8", PNG_COLOR_TYPE_RGB, 8});
  const auto size = fs::file_size(good);
  const std::string cut = tmp("cut.png"), flipped = tmp("flipped.png");
  fs::copy_file(good, cut);
  fs::resize_file(cut, size / 2);
  fs::copy_file(good, flipped);
  {
    std::FILE* f = std::fopen(flipped.c_str(), "r+b");
    ASSERT_NE(f, nullptr);
    std::fseek(f, 40, SEEK_SET);  // inside IDAT's compressed data, past the header chunks
    std::fputc(0x5a, f);
    std::fseek(f, 60, SEEK_SET);
    std::fputc(0xa5, f);
    std::fclose(f);
  }
  // A text chunk whose length claims 1.8 GB in a file of a few hundred bytes: refused before libpng allocates it.
  const std::string liar = tmp("liar.png");
  {
    std::string bytes;
    {
      std::ifstream in(good, std::ios::binary);
      bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string chunk = std::string("\x6f\x00\x00\x00tEXt", 8) + "Comment";  // 1862270976 bytes claimed
    bytes.insert(33, chunk);                                                       // after the signature and IHDR
    std::ofstream(liar, std::ios::binary) << bytes;
  }
  for (const std::string& path : {cut, flipped, liar}) {
    try {
      (void)envkit::read_image(path);
      ADD_FAILURE() << path << " was read";
    } catch (const envkit::Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      if (path == liar) {
        EXPECT_NE(what.find("claims 1862270976 bytes"), std::string::npos) << what;
      }
    }
  }
}
