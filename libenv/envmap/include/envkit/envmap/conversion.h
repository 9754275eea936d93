#pragma once
/// @file conversion.h
/// A conversion of an environment map to another parameterization, convention, orientation or size, as one typed
/// request: what envconvert's options and EnvMap.convert's arguments say once their names are parsed. validate()
/// checks every combination in one place and convert() performs it, so the tool and the Python module refuse the
/// same requests and produce the same pixels. Errors name the request's fields (ConversionField); each front end
/// maps them to its own option names.
#include <envkit/core/error.h>
#include <envkit/core/vec.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/parameterization.h>
#include <envkit/maps/view.h>
#include <envkit/resample/filter.h>
#include <envkit/resample/resample.h>

#include <optional>
#include <string>

namespace envkit {

struct ConversionRequest {
  Kind to = Kind::LatLong;  ///< the output's parameterization
  /// Natural size N (param_factory.h: lat-long 2N x N, cube faces N x N, camera views N wide); empty: about the
  /// source's texel density (matching_natural_size).
  std::optional<int> size;
  /// Camera views: the image height in texels, instead of size / aspect.
  std::optional<int> height;
  /// The output's convention; empty: the source map's.
  const Convention* convention = nullptr;
  /// Cube outputs: the layout; empty: the convention's (a vertical strip for six face files).
  std::optional<CubeLayout> layout;
  /// Camera-view outputs (perspective, fisheye): the view; empty: view.h's defaults with default_fov_degrees(to).
  std::optional<ViewParams> view;
  /// Camera-view outputs: width / height; empty: 1.
  std::optional<double> aspect;
  Filter filter = Filter::Area;
  /// R applied on top of the source's orientation: what the source shows in direction d, the output shows in R d.
  /// Empty: the source's orientation.
  std::optional<Mat3> rotation;
  /// The file the output is written to, when it is (its extension decides what pixel_type and compression may
  /// be; a '%' in it writes six cube faces); empty: the output stays in memory.
  std::string output;
  PixelType pixel_type = PixelType::Auto;
  std::string compression;  ///< empty: the writer's default
};

/// The field of a ConversionRequest a refusal concerns.
enum class ConversionField {
  Layout,       ///< a layout for a map that is no cube, or not the vertical strip six face files are
  Output,       ///< six face files ('%' in the output) for a map that is no cube
  PixelType,    ///< half floats for an output that is not OpenEXR
  Compression,  ///< a compression the output's format does not take
  View,         ///< a view for an output that is no camera view, or a view out of the lens's range
  Aspect,       ///< an aspect for an output that is no camera view
  Height,       ///< a height for an output that is no camera view, or together with an aspect
  Size,         ///< an output too large to make (the message is check_request_size's)
};

/// A request validate() or convert() refuses. what() speaks the library's terms ("layout: applies to cube maps
/// only"); `message` is the problem without the field's name, for front ends that name the field their own way.
class ConversionError : public Error {
 public:
  ConversionError(ConversionField at, const std::string& problem, const std::string& rejected = {});
  ConversionField field;
  std::string message;
  /// The rejected value where one is at fault (the size N of a Size refusal), else empty.
  std::string value;
};

/// The request's name of a field ("layout", "pixel_type", ...), as what() prints it.
const char* conversion_field_name(ConversionField field);

/// Throws ConversionError unless the request is one convert() can perform: every combination of its fields, the
/// view against its lens, and (when `size` is given) the output's size against check_request_size. Reads no file.
void validate(const ConversionRequest& request);

/// The convention the output is written for: the request's, else the source's.
const Convention& output_convention(const ConversionRequest& request, const EnvMap& source);

/// The output's layout at the size the request gives or, without one, the natural size that keeps about the
/// source's texel density. Throws ConversionError(Size) when that output is too large to make.
ParamSpec output_spec(const EnvMap& source, const ConversionRequest& request);

/// Resamples `source` as `request` says (validate() first) onto `spec` (output_spec()): a new map in the output
/// convention, with no rotation of its own, and the source's metadata but for its envkit:* keys (they describe
/// the source's file). `progress` gets the fraction done.
EnvMap convert(const EnvMap& source, const ConversionRequest& request, const ParamSpec& spec,
               const ProgressFn& progress = {});
/// The same onto output_spec(source, request).
EnvMap convert(const EnvMap& source, const ConversionRequest& request, const ProgressFn& progress = {});

}  // namespace envkit
