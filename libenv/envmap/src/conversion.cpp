#include <envkit/envmap/conversion.h>
#include <envkit/io/request_limits.h>
#include <envkit/maps/view_spec.h>
#include <envkit/resample/map_size.h>

#include <algorithm>
#include <cctype>
#include <filesystem>

namespace envkit {

namespace {

/// Bytes per output texel: the output image, the resampler's footprint tables and the encoder's copy.
constexpr double kConvertBytesPerTexel = 32.0;

bool is_view_kind(Kind kind) { return kind == Kind::Perspective || kind == Kind::Fisheye; }

bool has_extension(const std::string& path, const std::string& ext) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e == ext;
}

[[noreturn]] void refuse(ConversionField field, const std::string& message, const std::string& value = {}) {
  throw ConversionError(field, message, value);
}

/// Six face files are a cube in a vertical strip; else the request's layout (empty: the convention's).
std::optional<CubeLayout> output_layout(const ConversionRequest& r) {
  if (is_face_pattern(r.output)) return CubeLayout::VerticalStrip;
  return r.layout;
}

ViewParams output_view(const ConversionRequest& r) {
  if (r.view) return *r.view;
  ViewParams v;
  v.fov_degrees = default_fov_degrees(r.to);
  return v;
}

/// The output's spec at natural size N.
ParamSpec spec_at(const ConversionRequest& r, const Convention& conv, int n) {
  if (!is_view_kind(r.to)) return spec_for(r.to, n, conv, output_layout(r));
  ParamSpec s = view_spec(r.to, n, r.aspect.value_or(1.0), output_view(r), conv);
  if (r.height) s.height = *r.height;
  return s;
}

void check_size(const ConversionRequest& r, const Convention& conv, int n) {
  const ParamSpec spec = spec_at(r, conv, n);
  try {
    check_request_size(kind_name(r.to) + " output", spec.width, spec.height, kConvertBytesPerTexel);
  } catch (const RequestTooLarge& e) {
    refuse(ConversionField::Size, e.what(), std::to_string(n));
  }
}

void check_layout(const ConversionRequest& r) {
  if (r.layout && r.to != Kind::CubeMap) refuse(ConversionField::Layout, "applies to cube maps only");
  if (!is_face_pattern(r.output)) return;
  if (r.to != Kind::CubeMap)
    refuse(ConversionField::Output, "a '%' pattern writes six cube faces: it needs a cube map");
  if (r.layout && *r.layout != CubeLayout::VerticalStrip)
    refuse(ConversionField::Layout, "does not apply to six face files ('%' in the output)");
}

void check_encoding(const ConversionRequest& r) {
  if (r.pixel_type == PixelType::Half && !has_extension(r.output, ".exr"))
    refuse(ConversionField::PixelType, "half floats need an OpenEXR (.exr) output");
  if (r.compression.empty()) return;
  // Only OpenEXR and TIFF writers take a compression; for other formats it would be silently ignored.
  const bool exr = has_extension(r.output, ".exr");
  if (!exr && !has_extension(r.output, ".tif") && !has_extension(r.output, ".tiff"))
    refuse(ConversionField::Compression, "applies to OpenEXR (.exr) and TIFF (.tif) outputs only, not '" +
                                             std::filesystem::path(r.output).filename().string() + "'");
  if (exr && !is_exr_compression(r.compression))
    refuse(ConversionField::Compression,
           "'" + r.compression + "' is not an OpenEXR compression (" + exr_compression_list() + ")");
}

void check_view_fields(const ConversionRequest& r) {
  const bool view = is_view_kind(r.to);
  if (r.view && !view)
    refuse(ConversionField::View, "describes a camera view: the output is no perspective or fisheye");
  if (r.aspect && !view) refuse(ConversionField::Aspect, "applies to camera views (perspective, fisheye) only");
  if (r.height && !view) refuse(ConversionField::Height, "applies to camera views (perspective, fisheye) only");
  if (r.height && r.aspect) refuse(ConversionField::Height, "give either a height or an aspect, not both");
  if (!view) return;
  try {
    check_view(r.to, output_view(r));
  } catch (const Error& e) {
    refuse(ConversionField::View, e.what());
  }
}

}  // namespace

ConversionError::ConversionError(ConversionField at, const std::string& problem, const std::string& rejected)
    : Error(std::string(conversion_field_name(at)) + ": " + problem), field(at), message(problem), value(rejected) {}

const char* conversion_field_name(ConversionField field) {
  switch (field) {
    case ConversionField::Layout:
      return "layout";
    case ConversionField::Output:
      return "output";
    case ConversionField::PixelType:
      return "pixel_type";
    case ConversionField::Compression:
      return "compression";
    case ConversionField::View:
      return "view";
    case ConversionField::Aspect:
      return "aspect";
    case ConversionField::Height:
      return "height";
    case ConversionField::Size:
      return "size";
  }
  return "?";
}

void validate(const ConversionRequest& r) {
  check_layout(r);
  check_encoding(r);
  check_view_fields(r);
  // Before anything is read: an impossible size is a refusal, not a late "out of memory". Without a convention
  // of its own, the output's is not known yet; envkit's stands in (convert() checks the final spec again).
  if (r.size) check_size(r, r.convention ? *r.convention : convention("envkit"), *r.size);
}

const Convention& output_convention(const ConversionRequest& r, const EnvMap& source) {
  return r.convention ? *r.convention : convention(source.convention);
}

ParamSpec output_spec(const EnvMap& source, const ConversionRequest& r) {
  const Convention& conv = output_convention(r, source);
  const auto spec_of_size = [&](int n) { return spec_at(r, conv, n); };
  const int n = r.size ? *r.size : matching_natural_size(data_texel_count(source.image, *source.param), spec_of_size);
  check_size(r, conv, n);
  return spec_of_size(n);
}

EnvMap convert(const EnvMap& source, const ConversionRequest& r, const ParamSpec& spec, const ProgressFn& progress) {
  EnvMap out;
  out.param = make_parameterization(spec);
  out.convention = output_convention(r, source).name;
  ResampleOptions ro;
  ro.filter = r.filter;
  ro.progress = progress;
  const MapRef from{source.image, *source.param,
                    r.rotation ? compose(*r.rotation, source.to_world()) : source.to_world()};
  out.image = resample(from, *out.param, out.to_world(), ro);
  // The source's envkit:* keys (its layout, face, rotation, source, ...) would describe the wrong map.
  std::erase_if(out.image.metadata, [](const auto& kv) { return kv.first.rfind("envkit:", 0) == 0; });
  return out;
}

EnvMap convert(const EnvMap& source, const ConversionRequest& r, const ProgressFn& progress) {
  return convert(source, r, output_spec(source, r), progress);
}

}  // namespace envkit
