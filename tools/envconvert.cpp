// envconvert: converts an environment map between parameterizations, conventions and orientations.
// A thin shell over libenv: its options become one ConversionRequest (validated before anything is read), then
// load_envmap -> convert -> save_envmap, with one-line errors.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/conversion.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/color.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/view.h>
#include <envkit/maps/view_spec.h>

#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>

#include "common/cli.h"
#include "common/input.h"
#include "common/progress.h"

namespace {

namespace fs = std::filesystem;
namespace tools = envkit::tools;
using envkit::Kind;
using envkit::Vec3;

const char* kFooter = R"(KIND and size for --size N: latlong 2N x N, cube faces N x N, mirrorball N x N,
angular N x N, octahedral N x N, paraboloid 2N x N, healpix 4N x 3N (N = N_side: the 12 base pixels as
N x N squares, 4 per row: north, equatorial, south), perspective and fisheye N wide, N / --aspect high,
skylatlong 4N x N and skyangular N x N (skylibs' sky formats: the upper hemisphere only; directions below the
horizon come out with alpha 0 when converting from them).
Camera views (--to perspective|fisheye; or --from one when --to is a map): --view-dir x,y,z or yaw,pitch
(degrees; yaw about +Y from +Z towards +X), --roll, --fov (perspective: across the width, or the height with
--fov-axis v; fisheye: across the image circle, up to 360), --lens. A view is recorded in the output's
metadata (envkit:view) and re-read from it; directions a view does not see come out with alpha 0.
Cube layouts L: vstrip (N x 6N, faces +X -X +Y -Y +Z -Z top to bottom), hstrip (6N x N), hcross (4N x 3N),
vcross (3N x 4N). A '%' in OUT writes six face files, '%' replaced by +X, -X, +Y, -Y, +Z, -Z (as exrenvmap
does); a '%' in IN reads six faces.
Without --from the input's parameterization comes from envkit or OpenEXR metadata, else from the aspect
ratio (2:1 latlong, 1:1 angular or octahedral, 1:6 6:1 4:3 3:4 cube), and the guess is printed; a 4:1
skylatlong or a skyangular needs --from (or the metadata envconvert writes).
Conventions (--convention, --from-convention): envkit (default), openexr (exrenvmap: corner-sampled,
N x 6N cube; writes the envmap attribute), hdrshop, angmap-cal, blender, gl (GL/Vulkan/KTX cube faces; also
Filament's cmgen), threejs, directx (DDS cubes), unity, mitsuba (Mitsuba 3 envmap), pbrt (pbrt-v4 equal-area
octahedral), renderman (OIIO z-up). Files without envkit metadata take it from OIIO's oiio:updirection and
oiio:sampleborder tags, which outputs carry where they apply.
--rotate R: the output shows the input environment rotated by R = Ry(yaw) Rx(pitch) Rz(roll): what the
input shows in direction d, the output shows in direction R d (yaw about +Y, the up axis).
--filter area integrates over each output texel and conserves power; nearest/bilinear/bicubic sample at
texel centres (faster; they alias and lose or gain power when shrinking).

Examples:
  envconvert sky.hdr -o sky_cube.exr --to cube
      lat-long -> vertical-strip cube with about the same texel density
  envconvert sky.exr -o exr_cube.exr --to cube --convention openexr --size 256 --half
      an N x 6N cube that exrenvmap and OpenEXR-based renderers read
  envconvert sky.exr -o 'face_%.png' --to cube --convention gl --size 512
      six GL/KTX faces face_+X.png ... face_-Z.png
  envconvert 'face_%.png' -o sky.exr --to latlong --size 1024
      six faces back to a 2048 x 1024 lat-long
  envconvert probe.hdr -o sky.exr --to latlong --from angular --from-convention hdrshop
  envconvert ball.jpg -o sky.exr --to latlong --from mirrorball --ball-centre 1012,998 --ball-radius 880
  envconvert sky.exr -o blender.exr --to latlong --convention blender --rotate 90,0,0
  envconvert sky.exr -o pbrt_sky.exr --to octahedral --convention pbrt --size 1024
      the equal-area square pbrt-v4's ImageInfiniteLight reads (+Z up)
  envconvert sky.exr -o fixed.exr --to latlong --fix-nonfinite zero
  envconvert sky.exr -o sky_hpx.exr --to healpix --size 256
      HEALPix N_side 256 (1024 x 768), every texel 4 pi / (12 N_side^2) sr
  envconvert sky.exr -o view.exr --to perspective --view-dir 30,10 --fov 60 --aspect 1.5 --size 960
      a 960 x 640 pinhole view 30 degrees left of +Z, 10 up, 60 degrees wide (area filter: no aliasing)
  envconvert fish.exr -o sky.exr --to latlong --from fisheye --lens equisolid --fov 185 --view-dir 0,90
      embed a fisheye photograph looking up into a lat-long (alpha 0 where the lens does not see)
  envconvert sky.exr -o sky_top.exr --to skylatlong --size 256
      the upper hemisphere as skylibs' 1024 x 256 sky lat-long (zenith on the top row)
  envconvert sky_top.exr -o sky.exr --to latlong --from skylatlong
      back to a full lat-long: alpha 0 below the horizon

Exit status: 0 success; 1 error (one line on stderr, no output file written); 2 usage error.)";

struct Options {
  tools::InputSpec in;
  std::string out, ball_centre, compression, view_dir, fov_axis;
  Kind to = Kind::LatLong;
  std::optional<envkit::CubeLayout> layout;
  envkit::Filter filter = envkit::Filter::Area;
  const envkit::Convention* convention = nullptr;
  std::optional<envkit::Mat3> rotation;
  std::string rotate;  ///< --rotate as given, for the closing line
  std::optional<envkit::Lens> lens;
  std::optional<double> roll, fov;
  double aspect = 1.0;
  int size = 0, threads = 0;
  bool half = false, force = false, quiet = false, progress = false;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("IN", o.in.path, "input map (a '%' reads six cube faces)")->required()->type_name("FILE");
  app.add_option("-o,--output", o.out, "output map (a '%' writes six cube faces)")->required()->type_name("OUT");
  tools::add_parsed_option(app, "--to", o.to, envkit::parse_kind, "output parameterization: " + tools::kind_choices())
      ->required()
      ->type_name("KIND");
  tools::add_parsed_option(app, "--from", o.in.from, envkit::parse_kind, "input parameterization (default: detected)")
      ->type_name("KIND");
  tools::add_parsed_option(app, "--layout", o.layout, envkit::parse_layout,
                           "cube layout: " + tools::layout_choices() + " (default: the convention's)")
      ->type_name("L");
  app.add_option("--size", o.size,
                 "natural size N (default: about the input's texel density, a multiple of 8 from 64 up)")
      ->type_name("N")
      ->transform(tools::integer_in(1, 1 << 17));
  tools::add_parsed_option(app, "--filter", o.filter, envkit::parse_filter,
                           std::string("resampling filter: ") + tools::kFilterChoices)
      ->type_name("F")
      ->default_str("area");
  tools::add_parsed_option(app, "--convention", o.convention, tools::convention_named,
                           "output convention: " + tools::convention_choices() +
                               " (default: the input's when its metadata names one, else envkit)")
      ->type_name("C");
  tools::add_parsed_option(app, "--from-convention", o.in.convention, tools::convention_named,
                           "convention of the input (default: from metadata, else envkit)")
      ->type_name("C");
  tools::add_parsed_option(
      app, "--rotate", o.rotation,
      [&o](const std::string& text) {
        o.rotate = text;
        return envkit::parse_rotation(text);
      },
      "rotate the environment: yaw,pitch,roll in degrees or 9 matrix entries")
      ->type_name("R");
  tools::add_parsed_option(app, "--colorspace", o.in.colorspace, envkit::canonical_colorspace,
                           "colour space of the input pixels (default: from the file)")
      ->type_name("CS");
  tools::add_threads_option(app, o.threads);
  tools::add_fix_nonfinite_option(app, o.in);
  app.add_flag("--half", o.half,
               "write half floats (OpenEXR output only); half cannot hold a sun: values above 65504 are clamped, "
               "with a warning");
  app.add_option("--compression", o.compression,
                 "output compression: OpenEXR none|rle|zips|zip|piz|pxr24|b44|b44a|dwaa|dwab (default zip), "
                 "or what OpenImageIO accepts for the format")
      ->type_name("C");
  app.add_option("--ball-centre,--ball-center", o.ball_centre, "mirror-ball photograph: ball centre in pixels")
      ->type_name("X,Y");
  app.add_option("--ball-radius", o.in.ball_radius, "mirror-ball photograph: ball radius in pixels")
      ->type_name("R")
      ->check(tools::number_in(0.0, 1e7, true));
  app.add_option("--view-dir", o.view_dir, "camera view: where it looks, x,y,z or yaw,pitch in degrees (default 0,0,1)")
      ->type_name("D");
  app.add_option("--roll", o.roll, "camera view: roll in degrees (the camera turned counter-clockwise)")
      ->type_name("DEG")
      ->check(tools::number_in(-1e6, 1e6));
  app.add_option("--fov", o.fov, "camera view: field of view in degrees (default 90; fisheye 180)")
      ->type_name("DEG")
      ->check(tools::number_in(0.0, 360.0, true));
  app.add_option("--fov-axis", o.fov_axis, "perspective: the extent --fov spans, h (width, default) or v (height)")
      ->type_name("h|v")
      ->check(CLI::IsMember({"h", "v"}));
  tools::add_parsed_option(app, "--lens", o.lens, envkit::parse_lens,
                           "fisheye lens: equidistant (default), equisolid, orthographic, stereographic")
      ->type_name("L");
  app.add_option("--aspect", o.aspect, "camera view output: width / height (default 1)")
      ->type_name("A")
      ->check(tools::number_in(1e-3, 1e3));
  app.add_flag("-f,--force", o.force, "allow OUT to overwrite IN");
  app.add_flag("-q,--quiet", o.quiet, "print only warnings and errors (no description, no progress)");
  app.add_flag("--progress", o.progress, "always show a progress bar (default: on a terminal, for large maps)");
  app.footer(kFooter);
}

bool is_view(Kind kind) { return kind == Kind::Perspective || kind == Kind::Fisheye; }

bool view_given(const Options& o) { return !o.view_dir.empty() || o.roll || o.fov || o.lens || !o.fov_axis.empty(); }

// The camera view the --view-dir/--roll/--fov/--fov-axis/--lens options describe, with the defaults of `kind`.
envkit::ViewParams view_params(const Options& o, Kind kind) {
  envkit::ViewParams v;
  v.fov_degrees = o.fov.value_or(envkit::default_fov_degrees(kind));
  v.roll_degrees = o.roll.value_or(0.0);
  if (!o.fov_axis.empty()) v.fov_axis = o.fov_axis == "v" ? envkit::FovAxis::Vertical : envkit::FovAxis::Horizontal;
  if (o.lens) v.lens = *o.lens;
  if (!o.view_dir.empty()) {
    std::vector<double> c;
    std::istringstream in(o.view_dir);
    for (std::string item; std::getline(in, item, ',');)
      c.push_back(tools::parse_number("--view-dir", item, -1e300, 1e300));
    if (c.size() == 2)
      v.forward = envkit::direction_from_yaw_pitch(c[0], c[1]);
    else if (c.size() == 3 && Vec3(c[0], c[1], c[2]).length() > 0.0)
      v.forward = Vec3(c[0], c[1], c[2]);
    else
      throw CLI::ValidationError("--view-dir", "'" + o.view_dir + "' is not x,y,z (non-zero) or yaw,pitch");
  }
  return v;
}

// The conversion the options ask for (each name was parsed once, as CLI11 read it). The view options describe the
// output when it is a camera view, else an input read --from perspective|fisheye (describe_input).
envkit::ConversionRequest conversion_request(const Options& o, std::optional<Kind> from) {
  envkit::ConversionRequest r;
  r.to = o.to;
  if (o.size > 0) r.size = o.size;
  // A convention read from the input's metadata carries over unless one is given for either side.
  if (o.convention)
    r.convention = o.convention;
  else if (o.in.convention)
    r.convention = &envkit::convention("envkit");
  r.layout = o.layout;
  const bool from_view = from && is_view(*from);
  if (view_given(o) && is_view(r.to))
    r.view = view_params(o, r.to);
  else if (view_given(o) && !from_view)
    r.view = envkit::ViewParams{};  // refused for being given at all (validate): the options' values are not read
  if (o.aspect != 1.0) r.aspect = o.aspect;
  r.filter = o.filter;
  r.rotation = o.rotation;
  r.output = o.out;
  r.pixel_type = o.half ? envkit::PixelType::Half : envkit::PixelType::Auto;
  r.compression = o.compression;
  return r;
}

// A refused request as the usage error (exit 2) naming the options at fault. `from_view`: --from is a camera view
// (the view options then describe the input, and only --aspect can be out of place).
CLI::ValidationError usage_error(const envkit::ConversionError& e, const envkit::ConversionRequest& r, bool from_view) {
  using Field = envkit::ConversionField;
  const char* const describe_a_view = "describe a camera view: add --to (or --from) perspective|fisheye";
  switch (e.field) {
    case Field::Layout:
      return CLI::ValidationError("--layout", r.to != Kind::CubeMap ? "applies to --to cube only" : e.message);
    case Field::Output:
      return CLI::ValidationError("--output", "a '%' pattern writes six cube faces: it needs --to cube");
    case Field::PixelType:
      return CLI::ValidationError("--half", e.message);
    case Field::Compression:
      return CLI::ValidationError("--compression", e.message);
    case Field::View:
      if (!is_view(r.to)) return CLI::ValidationError("--view-dir/--roll/--fov/--lens/--aspect", describe_a_view);
      return CLI::ValidationError("--fov/--lens", e.message);
    case Field::Aspect:
      if (!from_view) return CLI::ValidationError("--view-dir/--roll/--fov/--lens/--aspect", describe_a_view);
      return CLI::ValidationError("--aspect", "applies to --to perspective|fisheye");
    case Field::Height:  // no option sets it
      break;
    case Field::Size:
      return CLI::ValidationError("--size", "'" + e.value + "': " + e.message);
  }
  return CLI::ValidationError(conversion_field_name(e.field), e.message);
}

// Checks the request before anything is read; a refusal is a usage error naming the options.
void validate(const envkit::ConversionRequest& r, bool from_view) {
  try {
    envkit::validate(r);
  } catch (const envkit::ConversionError& e) {
    throw usage_error(e, r, from_view);
  }
}

// What the options say about the input beyond its path: a mirror-ball photograph's ball, non-finite values, and a
// camera view read --from perspective|fisheye. Usage errors (exit 2) before any file is touched.
void describe_input(Options& o, std::optional<Kind> from, Kind to) {
  if (!o.ball_centre.empty()) {
    const auto [x, y] = tools::parse_number_pair("--ball-centre", o.ball_centre);
    o.in.ball_cx = x;
    o.in.ball_cy = y;
  }
  if ((o.in.ball_cx || o.in.ball_radius) && from != Kind::MirrorBall)
    throw CLI::ValidationError("--ball-centre/--ball-radius",
                               "describe a mirror-ball photograph: add --from mirrorball");
  if (!view_given(o) || is_view(to) || !from || !is_view(*from)) return;
  o.in.view = view_params(o, *from);
  try {
    envkit::check_view(*from, *o.in.view);
  } catch (const envkit::Error& e) {
    throw CLI::ValidationError("--fov/--lens", e.what());
  }
}

int convert(Options& o) {
  const std::optional<Kind> from = o.in.from;
  const envkit::ConversionRequest request = conversion_request(o, from);
  validate(request, from && is_view(*from));
  describe_input(o, from, request.to);
  // Nothing is read before the paths are known to be sane: no surprises after a long conversion.
  envkit::install_temp_cleanup_on_signal();
  const std::vector<std::string> inputs = tools::input_paths(o.in.path);
  envkit::check_outputs(envkit::face_paths(o.out), inputs, o.force);
  const auto thread_limit = tools::limit_threads(o.threads);

  tools::LoadedInput in = tools::load_input(o.in);
  tools::report_input(in, o.quiet);

  envkit::ParamSpec spec;
  try {
    spec = envkit::output_spec(in.map, request);
  } catch (const envkit::ConversionError& e) {
    throw usage_error(e, request, from && is_view(*from));
  }
  const std::size_t work = static_cast<std::size_t>(spec.width) * spec.height;
  tools::ProgressBar bar("envconvert: resampling", tools::want_progress(o.progress, o.quiet, work));
  const envkit::EnvMap out = envkit::convert(in.map, request, spec, bar.callback());
  bar.finish();

  envkit::SaveOptions so;
  so.write.pixel_type = request.pixel_type;
  so.write.compression = request.compression;
  so.filter = envkit::filter_name(request.filter);
  so.source = fs::path(o.in.path).filename().string();
  const envkit::ClampReport clamped = envkit::save_envmap(o.out, out, so);
  if (clamped.any()) tools::warn(clamped.message(o.out));

  if (!o.quiet)
    tools::info(std::string("wrote ") + (envkit::is_face_pattern(o.out) ? "six faces " : "") + o.out + ": " +
                out.param->describe() + ", convention " + out.convention + ", filter " + so.filter +
                (o.rotate.empty() ? "" : ", rotated by " + o.rotate));
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Converts an environment map between parameterizations (lat-long, cube, mirror ball, angular,\n"
      "octahedral, dual paraboloid, HEALPix, perspective and fisheye views), conventions and orientations.",
      "envconvert");
  Options options;
  add_options(app, options);
  return tools::run_cli(app, argc, argv, [&] { return convert(options); });
}
