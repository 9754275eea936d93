#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/io/color.h>
#include <envkit/io/image_io.h>
#include <envkit/render/film.h>

#include <algorithm>
#include <cmath>

namespace envkit::render {

namespace {
double finite_or_zero(double v) { return std::isfinite(v) ? v : 0.0; }
}  // namespace

Film::Film(int full_width, int full_height, Crop crop)
    : full_width_(full_width), full_height_(full_height), crop_(crop) {
  if (crop.x0 < 0 || crop.y0 < 0 || crop.x1 > full_width || crop.y1 > full_height || crop.width() < 1 ||
      crop.height() < 1)
    throw Error("crop window " + std::to_string(crop.x0) + "," + std::to_string(crop.y0) + "," +
                std::to_string(crop.x1) + "," + std::to_string(crop.y1) + " is empty or outside the " +
                std::to_string(full_width) + "x" + std::to_string(full_height) + " image");
  pixels_.resize(std::size_t(crop.width()) * crop.height());
}

Vec3 Film::mean(int x, int y) const {
  const Pixel& p = pixels_[std::size_t(y) * crop_.width() + x];
  return p.count ? p.sum / double(p.count) : Vec3(0, 0, 0);
}

Vec3 Film::variance(int x, int y) const {
  const Pixel& p = pixels_[std::size_t(y) * crop_.width() + x];
  if (p.count < 2) return Vec3(0, 0, 0);
  const double n = double(p.count);
  Vec3 v;
  for (int c = 0; c < 3; ++c) {
    const double m = p.sum[c] / n;
    v[c] = finite_or_zero(std::max(0.0, (p.sum_sq[c] - n * m * m) / (n - 1.0)) / n);
  }
  return v;
}

std::uint64_t Film::total_samples() const {
  std::uint64_t n = 0;
  for (const Pixel& p : pixels_) n += p.count;
  return n;
}

Image Film::mean_image() const {
  Image image(width(), height(), 3);
  image.channel_names = {"R", "G", "B"};
  for (int y = 0; y < height(); ++y)
    for (int x = 0; x < width(); ++x) {
      const Vec3 m = mean(x, y);
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = float(finite_or_zero(m[c]));
    }
  return image;
}

void Film::write_exr(const std::string& path, const std::map<std::string, std::string>& metadata) const {
  const int w = width(), h = height();
  static const char* names[8] = {"R", "G", "B", "variance.R", "variance.G", "variance.B", "samples", "seconds"};
  const int channels = timed() ? 8 : 7;
  std::vector<float> data(std::size_t(w) * h * std::size_t(channels));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = &data[(std::size_t(y) * w + x) * std::size_t(channels)];
      const Vec3 m = mean(x, y), v = variance(x, y);
      for (int c = 0; c < 3; ++c) {
        p[c] = float(std::clamp(finite_or_zero(m[c]), -3.4e38, 3.4e38));
        p[3 + c] = float(std::clamp(finite_or_zero(v[c]), 0.0, 3.4e38));
      }
      p[6] = float(count(x, y));
      if (timed()) p[7] = float(seconds(x, y));
    }
  AtomicOutput out(path);
  try {
    // Two parts: "beauty" (R, G, B: what every EXR reader, envdiff and envinfo included, reads as subimage 0)
    // and "aov" (variance.R/G/B, samples, and seconds when timed).
    const Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(full_width_ - 1, full_height_ - 1));
    const Imath::Box2i window(Imath::V2i(crop_.x0, crop_.y0), Imath::V2i(crop_.x1 - 1, crop_.y1 - 1));
    std::vector<Imf::Header> headers(2, Imf::Header(display, window));
    const char* part_names[2] = {"beauty", "aov"};
    for (int part = 0; part < 2; ++part) {
      Imf::Header& header = headers[std::size_t(part)];
      header.setName(part_names[part]);
      header.setType(Imf::SCANLINEIMAGE);
      header.compression() = Imf::ZIP_COMPRESSION;
      for (int c = part == 0 ? 0 : 3; c < (part == 0 ? 3 : channels); ++c)
        header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
      header.insert("chromaticities", Imf::ChromaticitiesAttribute(Imf::Chromaticities()));
      for (const auto& [key, value] : metadata) header.insert(key, Imf::StringAttribute(value));
    }
    const std::size_t xs = std::size_t(channels) * sizeof(float), ys = xs * std::size_t(w);
    // OpenEXR addresses pixels by absolute (data window) coordinates: shift the base pointer.
    char* base = reinterpret_cast<char*>(data.data()) - std::ptrdiff_t(crop_.x0) * std::ptrdiff_t(xs) -
                 std::ptrdiff_t(crop_.y0) * std::ptrdiff_t(ys);
    Imf::MultiPartOutputFile file(out.temp_path().c_str(), headers.data(), 2);
    for (int part = 0; part < 2; ++part) {
      Imf::FrameBuffer frame;
      for (int c = part == 0 ? 0 : 3; c < (part == 0 ? 3 : channels); ++c)
        frame.insert(names[c], Imf::Slice(Imf::FLOAT, base + std::size_t(c) * sizeof(float), xs, ys));
      Imf::OutputPart output(file, part);
      output.setFrameBuffer(frame);
      output.writePixels(h);
    }
  } catch (const std::exception& e) {
    fail(path, std::string("cannot write: ") + e.what());
  }
  out.commit();
}

void Film::write_preview(const std::string& path, const std::string& view) const {
  Image image = mean_image();
  encode_for_display(image, "sRGB", view);
  WriteOptions options;
  options.encode_colorspace = "raw";  // already display-encoded
  write_image(path, image, options);
}

}  // namespace envkit::render
