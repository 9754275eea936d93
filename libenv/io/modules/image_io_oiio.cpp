// envkit's OpenImageIO module (libenvkit_oiio.so): the image formats envkit does not decode itself (PNG, JPEG, TIFF,
// DDS, PNM, ...), behind the ImageBackend interface of libenv/io/src/image_backend.h. libenv loads it with dlopen on
// first need, so programs that only read OpenEXR, Radiance or PFM files never load OIIO.
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <memory>
#include <string>

#include "image_backend.h"

namespace envkit::detail {
namespace {

FileSpec to_file_spec(const OIIO::ImageInput& in, const OIIO::ImageSpec& spec) {
  FileSpec f;
  f.format = in.format_name();
  f.pixel_type = spec.format.c_str();
  f.floating_point = spec.format.is_floating_point();
  f.bits_per_sample = spec.get_int_attribute("oiio:BitsPerSample", 0);
  f.format_bytes = static_cast<int>(spec.format.size());
  f.deep = spec.deep;
  f.depth = spec.depth;
  f.width = spec.width, f.height = spec.height, f.nchannels = spec.nchannels;
  f.x = spec.x, f.y = spec.y, f.full_x = spec.full_x, f.full_y = spec.full_y;
  f.full_width = spec.full_width, f.full_height = spec.full_height;
  for (int c = 0; c < spec.nchannels; ++c) f.channel_names.push_back(spec.channel_name(c));
  f.alpha_channel = spec.alpha_channel;
  f.colorspace_tag = spec.get_string_attribute("oiio:ColorSpace");
  f.gamma = spec.get_float_attribute("oiio:Gamma", 2.2f);
  if (const OIIO::ParamValue* p = spec.find_attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8))) {
    f.has_chromaticities = true;
    std::copy_n(static_cast<const float*>(p->data()), 8, f.chromaticities.begin());
  }
  f.unassociated_alpha = spec.get_int_attribute("oiio:UnassociatedAlpha", 0) != 0;
  for (const OIIO::ParamValue& p : spec.extra_attribs) {
    const OIIO::TypeDesc t = p.type();
    if (t.arraylen != 0 || t.aggregate != OIIO::TypeDesc::SCALAR || p.nvalues() != 1) continue;
    const bool wanted = t.basetype == OIIO::TypeDesc::STRING || t.is_floating_point() ||
                        (t.basetype >= OIIO::TypeDesc::UINT8 && t.basetype <= OIIO::TypeDesc::INT64);
    if (wanted) f.metadata[p.name().string()] = p.get_string(1 << 16);
  }
  return f;
}

class Input final : public BackendInput {
 public:
  explicit Input(std::unique_ptr<OIIO::ImageInput> in)
      : in_(std::move(in)), spec_(to_file_spec(*in_, in_->spec(0, 0))) {}
  const FileSpec& spec() const override { return spec_; }
  std::string read(float* pixels) override {
    if (in_->read_image(0, 0, 0, spec_.nchannels, OIIO::TypeDesc::FLOAT, pixels)) return "";
    std::string err = in_->geterror();
    return err.empty() ? "read error" : err;
  }

 private:
  std::unique_ptr<OIIO::ImageInput> in_;
  FileSpec spec_;
};

OIIO::TypeDesc pixel_format(const std::string& name) {
  if (name == "half") return OIIO::TypeDesc::HALF;
  if (name == "uint8") return OIIO::TypeDesc::UINT8;
  if (name == "uint16") return OIIO::TypeDesc::UINT16;
  return OIIO::TypeDesc::FLOAT;
}

class Backend final : public ImageBackend {
 public:
  std::unique_ptr<BackendInput> open(const std::string& path, std::string& error, bool& unknown_format) override {
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path, &config);
    if (!in) {
      error = OIIO::geterror();
      unknown_format = error.find("could not find a format reader") != std::string::npos;
      return nullptr;
    }
    return std::make_unique<Input>(std::move(in));
  }

  bool writer_for(const std::string& path, WriterInfo& info) override {
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
      (void)OIIO::geterror();  // clear OIIO's pending message
      return false;
    }
    info.format = out->format_name();
    info.alpha = out->supports("alpha");
    return true;
  }

  std::string write(const std::string& file, const WriteSpec& w, const float* pixels) override {
    OIIO::ImageSpec spec(w.width, w.height, w.channels, pixel_format(w.pixel_type));
    spec.channelnames = w.channel_names;
    spec.alpha_channel = w.alpha_channel;
    if (w.unassociated_alpha) spec.attribute("oiio:UnassociatedAlpha", 1);
    for (const auto& [key, value] : w.attributes) spec.attribute(key, value);
    {
      auto out = OIIO::ImageOutput::create(file);
      if (!out) return OIIO::geterror();
      if (!out->open(file, spec)) return out->geterror();
      if (!out->write_image(OIIO::TypeDesc::FLOAT, pixels)) return out->geterror();
      if (!out->close()) return out->geterror();
    }  // destroyed before the check below: some OIIO writers finish the file in
       // their destructor
    // Cheap sanity check that a complete header landed on disk before the file replaces the target.
    auto in = OIIO::ImageInput::open(file);
    if (!in || in->spec().width != spec.width || in->spec().height != spec.height)
      return "the written file does not read back (" + OIIO::geterror() + ")";
    return "";
  }
};

}  // namespace
}  // namespace envkit::detail

extern "C" __attribute__((visibility("default"))) envkit::detail::ImageBackend* envkit_oiio_backend_v2() {
  // envkit parallelises with oneTBB; OIIO's own thread pool would only add idle threads that outlive the work (and
  // that LeakSanitizer's exit-time stop-the-world trips over in sanitizer builds).
  static const bool single_threaded = OIIO::attribute("threads", 1);
  (void)single_threaded;
  static envkit::detail::Backend backend;
  return &backend;
}
