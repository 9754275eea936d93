#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/oiio_env_tags.h>
#include <envkit/maps/latlong.h>

#include <filesystem>
#include <numeric>
#include <sstream>

namespace envkit {

namespace {

const char* kFaceNames[6] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

std::string ratio_text(int w, int h) {
  const int g = std::gcd(w, h);
  return std::to_string(w / g) + ":" + std::to_string(h / g);
}

std::string meta(const Image& image, const std::string& key) {
  auto it = image.metadata.find(key);
  return it == image.metadata.end() ? std::string() : it->second;
}

// True when every channel is zero at the four corners of the square [x0, x0+n) x [0, n) and not at its centre:
// the signature of a disk inscribed in that square.
bool looks_like_disk(const Image& img, int x0, int n) {
  if (n < 8) return false;
  const int pts[4][2] = {{x0, 0}, {x0 + n - 1, 0}, {x0, n - 1}, {x0 + n - 1, n - 1}};
  for (const auto& p : pts)
    for (int c = 0; c < img.color_channels(); ++c)
      if (img.at(p[0], p[1], c) != 0.0f) return false;
  for (int c = 0; c < img.color_channels(); ++c)
    if (img.at(x0 + n / 2, n / 2, c) != 0.0f) return true;
  return false;
}

// Does the image size fit the kind (and layout)? Empty string when it does, else what was expected.
std::string size_mismatch(Kind kind, int w, int h, std::optional<CubeLayout> layout, bool ball_given) {
  switch (kind) {
    case Kind::LatLong:
    case Kind::DualParaboloid:
      return w == 2 * h ? "" : "expects 2:1";
    case Kind::SkyLatLong:
      return w == 4 * h ? "" : "expects 4:1";
    case Kind::Octahedral:
    case Kind::AngularMap:
    case Kind::SkyAngular:
      return w == h ? "" : "expects 1:1";
    case Kind::MirrorBall:
      return (w == h || ball_given) ? "" : "expects 1:1 (or give the ball's centre and radius)";
    case Kind::HEALPix:
      return (w % 4 == 0 && 3 * w == 4 * h) ? "" : "expects 4 N_side x 3 N_side";
    case Kind::Perspective:
    case Kind::Fisheye:
      return "";
    case Kind::CubeMap:
      if (layout) return face_size_for(*layout, w, h) ? "" : "expects " + layout_name(*layout) + " proportions";
      for (CubeLayout l : {CubeLayout::VerticalStrip, CubeLayout::HorizontalStrip, CubeLayout::HorizontalCross,
                           CubeLayout::VerticalCross})
        if (face_size_for(l, w, h)) return "";
      return "expects 1:6, 6:1, 4:3 or 3:4";
  }
  return "";
}

std::optional<CubeLayout> layout_from_size(int w, int h) {
  for (CubeLayout l :
       {CubeLayout::VerticalStrip, CubeLayout::HorizontalStrip, CubeLayout::HorizontalCross, CubeLayout::VerticalCross})
    if (face_size_for(l, w, h)) return l;
  return std::nullopt;
}

}  // namespace

Mat3 EnvMap::to_world() const { return compose(rotation, envkit::convention(convention).frame(param->kind())); }

std::vector<std::string> face_paths(const std::string& pattern) {
  const auto pos = pattern.find('%');
  if (pos == std::string::npos) return {pattern};
  std::vector<std::string> paths;
  for (const char* name : kFaceNames) paths.push_back(pattern.substr(0, pos) + name + pattern.substr(pos + 1));
  return paths;
}

bool is_face_pattern(const std::string& path) { return path.find('%') != std::string::npos; }

Detection detect_parameterization(const Image& img, const std::string& path, const LoadOptions& opt) {
  const int w = img.width, h = img.height;
  const bool ball_given = opt.ball_cx || opt.ball_cy || opt.ball_radius;
  Detection d;
  std::string tagged_kind = meta(img, "envkit:parameterization");
  const std::string exr_envmap = meta(img, "envmap");
  // OpenEXR tools (exrenvmap) rewrite the envmap attribute but copy other attributes verbatim: when the two
  // disagree, the attribute describes the pixels and the envkit:* keys are stale.
  const bool stale_tags =
      (exr_envmap == "latlong" || exr_envmap == "cube") && !tagged_kind.empty() && tagged_kind != exr_envmap;
  if (stale_tags) tagged_kind.clear();
  const std::string tagged_convention = meta(img, "envkit:convention");
  // OIIO's environment tags only speak for files that say nothing more specific.
  std::optional<OiioEnvReading> oiio;
  if (!opt.convention && !stale_tags && tagged_convention.empty() && exr_envmap.empty())
    oiio = read_oiio_env_tags(img.metadata);
  d.convention = opt.convention               ? opt.convention->name
                 : stale_tags                 ? "openexr"
                 : !tagged_convention.empty() ? tagged_convention
                 : !exr_envmap.empty()        ? "openexr"
                 : oiio                       ? oiio->convention
                                              : "envkit";
  if (oiio) {
    d.grid = oiio->grid;
    d.convention_reason = "from its " + oiio->reason;
  }
  envkit::convention(d.convention);  // validates the name
  d.layout = opt.layout.value_or(envkit::convention(d.convention).cube_layout);
  if (opt.kind) {
    d.kind = *opt.kind;
    const std::string bad = size_mismatch(d.kind, w, h, opt.layout, ball_given);
    if (!bad.empty())
      fail(path, "aspect ratio " + ratio_text(w, h) + " (" + size_text(w, h) + ") contradicts --from " +
                     kind_name(d.kind) + " (" + bad + ")");
    if (d.kind == Kind::CubeMap && !opt.layout) {
      const std::string tagged_layout = meta(img, "envkit:layout");
      if (!tagged_layout.empty() && face_size_for(parse_layout(tagged_layout), w, h))
        d.layout = parse_layout(tagged_layout);
      else
        d.layout = *layout_from_size(w, h);
    }
    d.reason = "as given by --from";
    return d;
  }
  if (!tagged_kind.empty()) {
    d.kind = parse_kind(tagged_kind);
    if (d.kind == Kind::CubeMap && !opt.layout) {
      const std::string tagged_layout = meta(img, "envkit:layout");
      d.layout = tagged_layout.empty() ? layout_from_size(w, h).value_or(CubeLayout::VerticalStrip)
                                       : parse_layout(tagged_layout);
    }
    const std::string bad =
        size_mismatch(d.kind, w, h, d.kind == Kind::CubeMap ? std::optional(d.layout) : std::nullopt, ball_given);
    if (!bad.empty())
      fail(path, "metadata says " + tagged_kind + " but the image is " + size_text(w, h) + " (" + bad + ")");
    d.reason = "from its envkit:parameterization metadata";
    return d;
  }
  if (exr_envmap == "latlong" || exr_envmap == "cube") {
    d.kind = exr_envmap == "latlong" ? Kind::LatLong : Kind::CubeMap;
    d.layout = CubeLayout::VerticalStrip;
    const std::string bad = size_mismatch(d.kind, w, h, d.layout, false);
    if (!bad.empty())
      fail(path, "OpenEXR envmap attribute says " + exr_envmap + " but the image is " + size_text(w, h));
    d.reason = "from its OpenEXR envmap attribute (" + exr_envmap + ")";
    return d;
  }
  d.assumed = true;
  if (w == 2 * h) {
    const bool disks = looks_like_disk(img, 0, h) && looks_like_disk(img, h, h);
    d.kind = disks ? Kind::DualParaboloid : Kind::LatLong;
    d.reason = disks ? "from the 2:1 aspect ratio and the two disks" : "from the 2:1 aspect ratio";
  } else if (w == h) {
    const bool disk = looks_like_disk(img, 0, w);
    d.kind = disk ? Kind::AngularMap : Kind::Octahedral;
    d.reason = disk ? "from the 1:1 aspect ratio and its black corners (pass --from mirrorball for a ball photograph, "
                      "--from skyangular for an upper hemisphere)"
                    : "from the 1:1 aspect ratio without black corners";
  } else if (auto l = layout_from_size(w, h)) {
    d.kind = Kind::CubeMap;
    d.layout = opt.layout.value_or(*l);
    d.reason = "from the " + ratio_text(w, h) + " aspect ratio (" + layout_name(d.layout) + ")";
  } else if (w == 4 * h) {
    // Only skylatlong has 4:1, but a sky is too rare a guess to make silently: the user says so.
    fail(path, "cannot tell the parameterization of a " + size_text(w, h) +
                   " image (aspect 4:1); pass --from skylatlong for an upper-hemisphere lat-long");
  } else {
    fail(path,
         "cannot tell the parameterization of a " + size_text(w, h) + " image (aspect " + ratio_text(w, h) +
             "); pass --from latlong|cube|mirrorball|angular|octahedral|paraboloid|healpix|skylatlong|skyangular");
  }
  return d;
}

EnvMap make_envmap(Image image, const std::string& path, const LoadOptions& opt, Detection* detection) {
  const Detection d = detect_parameterization(image, path, opt);
  const Convention& conv = convention(d.convention);
  ParamSpec spec;
  spec.kind = d.kind;
  spec.width = image.width;
  spec.height = image.height;
  spec.layout = d.layout;
  spec.basis = conv.cube_basis;
  spec.grid =
      d.kind == Kind::LatLong ? conv.latlong_grid : (d.kind == Kind::CubeMap ? conv.cube_grid : TexelGrid::Centre);
  if (d.grid && (d.kind == Kind::LatLong || d.kind == Kind::CubeMap)) spec.grid = *d.grid;
  spec.ball_cx = opt.ball_cx;
  spec.ball_cy = opt.ball_cy;
  spec.ball_radius = opt.ball_radius;
  EnvMap map;
  try {
    if (opt.view)
      spec.view = *opt.view;
    else if (const std::string v = meta(image, "envkit:view"); !v.empty())
      spec.view = parse_view(v);
    map.param = make_parameterization(spec);
  } catch (const Error& e) {
    fail(path, e.what());
  }
  map.image = std::move(image);
  map.convention = conv.name;
  if (detection) *detection = d;
  return map;
}

EnvMap load_envmap(const std::string& path, const LoadOptions& opt, Detection* detection, ReadReport* report) {
  if (!is_face_pattern(path)) return make_envmap(read_image(path, opt.read, report), path, opt, detection);

  // Six faces, each square and of one size, assembled into a vertical strip in face order.
  const std::vector<std::string> paths = face_paths(path);
  Image strip;
  int n = 0;
  for (int f = 0; f < 6; ++f) {
    ReadReport face_report;
    const Image face = read_image(paths[f], opt.read, &face_report);
    if (face.width != face.height)
      fail(paths[f], "cube face is " + size_text(face.width, face.height) + ", not square");
    if (f == 0) {
      n = face.width;
      strip = Image(n, 6 * n, face.channels);
      strip.channel_names = face.channel_names;
      strip.alpha_channel = face.alpha_channel;
      strip.metadata = face.metadata;
    } else if (face.width != n) {
      fail(paths[f], "cube face is " + size_text(face.width, face.height) + " but " + paths[0] + " is " +
                         size_text(n, n) + ": all six faces must have the same size");
    } else if (face.channels != strip.channels) {
      fail(paths[f], "cube face has " + std::to_string(face.channels) + " channels but " + paths[0] + " has " +
                         std::to_string(strip.channels));
    }
    if (report && f == 0) {
      *report = face_report;
    } else if (report) {  // counts cover all six faces, not just the first
      report->nan_count += face_report.nan_count;
      report->posinf_count += face_report.posinf_count;
      report->neginf_count += face_report.neginf_count;
      report->negative_count += face_report.negative_count;
      report->replaced_count += face_report.replaced_count;
      report->notes.insert(report->notes.end(), face_report.notes.begin(), face_report.notes.end());
    }
    std::copy(face.pixels.begin(), face.pixels.end(),
              strip.pixels.begin() + static_cast<std::ptrdiff_t>(f) * n * n * strip.channels);
  }
  LoadOptions faces = opt;
  faces.kind = Kind::CubeMap;
  faces.layout = CubeLayout::VerticalStrip;
  EnvMap map = make_envmap(std::move(strip), path, faces, detection);
  if (detection) detection->reason = "six faces named by the '%' pattern";
  return map;
}

namespace {

// OpenEXR-conformant: what ImfEnvmap itself would compute for every texel.
std::string exr_envmap_attribute(const EnvMap& map, const std::string& path) {
  const std::filesystem::path p(path);
  std::string ext = p.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".exr" || map.convention != "openexr") return "";
  const Mat3 id = identity3();
  if (map.rotation != id) return "";
  if (map.param->kind() == Kind::LatLong) return map.param->grid() == TexelGrid::Corner ? "latlong" : "";
  if (const std::optional<CubeFaceLayout> cube = map.param->cube_faces())
    return cube->layout == CubeLayout::VerticalStrip && cube->basis == CubeBasis::Envkit &&
                   map.param->grid() == TexelGrid::Corner
               ? "cube"
               : "";
  return "";
}

}  // namespace

ClampReport save_envmap(const std::string& path, const EnvMap& map, const SaveOptions& opt) {
  WriteOptions w = opt.write;
  w.metadata["envkit:parameterization"] = kind_name(map.param->kind());
  w.metadata["envkit:convention"] = map.convention;
  w.metadata["envkit:description"] = map.param->describe();
  const std::optional<CubeFaceLayout> cube = map.param->cube_faces();
  if (cube) w.metadata["envkit:layout"] = layout_name(cube->layout);
  if (!opt.filter.empty()) w.metadata["envkit:filter"] = opt.filter;
  if (!opt.source.empty()) w.metadata["envkit:source"] = opt.source;
  if (const ViewParams* view = map.param->view()) w.metadata["envkit:view"] = format_view(*view);
  if (map.rotation != identity3()) w.metadata["envkit:rotation"] = format_matrix(map.rotation);
  for (const auto& [key, value] : oiio_env_tags_for(*map.param, map.to_world())) w.metadata[key] = value;

  // Never write a map that load_envmap would refuse to read back as what its metadata says it is.
  const std::string bad = size_mismatch(map.param->kind(), map.image.width, map.image.height,
                                        cube ? std::optional(cube->layout) : std::nullopt, false);
  if (!bad.empty())
    fail(path, "a " + size_text(map.image.width, map.image.height) + " " + kind_name(map.param->kind()) +
                   " map could not be read back (a " + kind_name(map.param->kind()) + " map " + bad + ")");
  if (!is_face_pattern(path)) {
    w.envmap_attribute = exr_envmap_attribute(map, path);
    return write_image(path, map.image, w);
  }
  if (!cube || cube->layout != CubeLayout::VerticalStrip)
    fail(path, "a '%' output pattern writes six cube faces: the map must be a cube map (--to cube)");
  const int n = cube->face_size;
  const std::vector<std::string> paths = face_paths(path);
  w.metadata["envkit:layout"] = "faces";
  // Write every face to its temp file first, then commit them as one group: six faces or none, also on a signal.
  OutputGroup group;
  ClampReport clamped;
  for (int f = 0; f < 6; ++f) {
    Image face(n, n, map.image.channels);
    face.channel_names = map.image.channel_names;
    face.alpha_channel = map.image.alpha_channel;
    face.metadata = map.image.metadata;
    const auto begin = map.image.pixels.begin() + static_cast<std::ptrdiff_t>(f) * n * n * map.image.channels;
    std::copy(begin, begin + static_cast<std::ptrdiff_t>(n) * n * map.image.channels, face.pixels.begin());
    WriteOptions fw = w;
    fw.metadata["envkit:face"] = kFaceNames[f];
    clamped.add(write_image(paths[f], face, fw));
  }
  group.commit();
  return clamped;
}

}  // namespace envkit
