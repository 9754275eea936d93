#pragma once
/// @file oiio_env_tags.h
/// OpenImageIO's environment-map metadata, as its texture system reads it from an image's spec
/// (src/libtexture/environment.cpp). OIIO's OpenEXR reader sets both for files with the envmap attribute
/// ("y", 1), and maketx requests them for OpenEXR outputs; OIIO 2.4's writers do not store them in files
/// (checked with oiiotool and maketx 2.4.7), but its readers return them when a file carries them as plain
/// attributes, as envkit's writers store them:
///  - "oiio:updirection" (string): "y" means the OpenEXR lat-long (+Y up, right-handed, centre of the image sees
///    +Z, three quarters across -X): envkit's own frame. "z" means RenderMan's lat-long (+Z up, left-handed,
///    s = atan2(y, x) / 2 pi + 1/2): envkit's "renderman" convention. OIIO itself only applies it to lat-longs.
///  - "oiio:sampleborder" (int): nonzero puts the first and last texel centres exactly on the poles / seam / cube
///    edges (s = i / (W - 1): TexelGrid::Corner); 0 or absent keeps centres at (i + 0.5) / W (TexelGrid::Centre).
/// envkit reads them from files that carry neither envkit:convention nor OpenEXR's envmap attribute (whose
/// meaning is fixed), and writes them for every lat-long and cube map whose frame and grid they can describe.
#include <envkit/core/vec.h>
#include <envkit/maps/parameterization.h>

#include <map>
#include <optional>
#include <string>

namespace envkit {

/// What a file's OIIO environment tags say, in envkit's terms.
struct OiioEnvReading {
  /// "envkit" ("y"), "openexr" ("y" with a sample border: exactly OpenEXR's corner-sampled maps) or
  /// "renderman" ("z"); "envkit" when only oiio:sampleborder is present (OIIO's "latlong_up" default is "y").
  std::string convention;
  /// Grid for lat-long and cube maps when oiio:sampleborder is present and the convention's own grid differs.
  std::optional<TexelGrid> grid;
  /// One line for users, e.g. "oiio:updirection=z, oiio:sampleborder=1".
  std::string reason;
};

/// Reads the tags from image metadata (integer attributes arrive as decimal text). nullopt when neither tag is
/// present or oiio:updirection is neither "y" nor "z".
std::optional<OiioEnvReading> read_oiio_env_tags(const std::map<std::string, std::string>& metadata);

/// The tags describing a map with texel layout `param` and map-frame -> world matrix `to_world`:
/// oiio:updirection for lat-longs whose to_world is the identity ("y") or RenderMan's frame ("z"), within 1e-9;
/// oiio:sampleborder ("0" or "1") for lat-longs and cubes on a Centre or Corner grid. Empty when none applies.
std::map<std::string, std::string> oiio_env_tags_for(const Parameterization& param, const Mat3& to_world);

/// Metadata keys OIIO reads as integers (writers store these as integer attributes where the format can).
bool is_oiio_int_tag(const std::string& key);

}  // namespace envkit
