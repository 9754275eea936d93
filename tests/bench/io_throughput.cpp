// One timed image read or write, by envkit (read_image / write_image) or by OpenImageIO, for scripts/bench/bench_io.sh,
// and a conversion's I/O floor for scripts/bench/bench_io_floor.sh.
//
//   io_throughput envkit|oiio read  IN         time reading IN into float RGB(A)
//   io_throughput envkit|oiio write IN OUT     read IN (untimed), time writing OUT (format from the extension)
//   io_throughput envkit floor IN RESULT OUT [COMPRESSION]
//       a conversion's I/O floor: read RESULT (a conversion's output, untimed), then time reading IN and writing
//       RESULT's pixels to OUT (same format; COMPRESSION as envconvert's --compression): what the conversion
//       IN -> RESULT would take without resampling
//
// Prints "<seconds> <megabytes of float pixels>"; the script turns the pair into MB/s.
#include <OpenImageIO/imageio.h>
#include <envkit/core/image.h>
#include <envkit/io/image_io.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

namespace {

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

int usage() {
  std::fprintf(stderr, "usage: io_throughput envkit|oiio read IN | write IN OUT | envkit floor IN RESULT OUT [COMP]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) return usage();
  const std::string lib = argv[1], op = argv[2], in = argv[3];
  if (op == "write" && argc < 5) return usage();
  if (op == "floor") {
    if (lib != "envkit" || argc < 6) return usage();
    const envkit::Image result = envkit::read_image(argv[4]);
    envkit::WriteOptions options;
    if (argc > 6) options.compression = argv[6];
    const double t0 = now();
    const envkit::Image input = envkit::read_image(in);
    envkit::write_image(argv[5], result, options);
    std::printf("%.4f %.1f\n", now() - t0, static_cast<double>(input.pixels.size() + result.pixels.size()) * 4e-6);
    return 0;
  }
  const envkit::Image image = op == "write" ? envkit::read_image(in) : envkit::Image();
  double t0 = 0, t1 = 0, mb = 0;
  if (lib == "envkit") {
    t0 = now();
    if (op == "read") {
      const envkit::Image r = envkit::read_image(in);
      mb = static_cast<double>(r.pixels.size()) * 4e-6;
    } else {
      envkit::write_image(argv[4], image);
      mb = static_cast<double>(image.pixels.size()) * 4e-6;
    }
    t1 = now();
  } else if (lib == "oiio") {
    t0 = now();
    if (op == "read") {
      auto input = OIIO::ImageInput::open(in);
      if (!input) return std::fprintf(stderr, "%s\n", OIIO::geterror().c_str()), 1;
      const OIIO::ImageSpec& spec = input->spec();
      std::vector<float> pixels(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
      if (!input->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels.data()))
        return std::fprintf(stderr, "%s\n", input->geterror().c_str()), 1;
      mb = static_cast<double>(pixels.size()) * 4e-6;
    } else {
      auto out = OIIO::ImageOutput::create(argv[4]);
      OIIO::ImageSpec spec(image.width, image.height, image.channels, OIIO::TypeDesc::FLOAT);
      spec.attribute("compression", "zip");
      if (!out || !out->open(argv[4], spec) || !out->write_image(OIIO::TypeDesc::FLOAT, image.pixels.data()) ||
          !out->close())
        return std::fprintf(stderr, "%s\n", OIIO::geterror().c_str()), 1;
      mb = static_cast<double>(image.pixels.size()) * 4e-6;
    }
    t1 = now();
  } else {
    return usage();
  }
  std::printf("%.4f %.1f\n", t1 - t0, mb);
  return 0;
}
