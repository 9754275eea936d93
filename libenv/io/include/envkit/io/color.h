#pragma once
/// @file color.h
/// Colour management through OpenColorIO.
///
/// Working space: the OCIO role `scene_linear` of the active config. With envkit's shipped config that is
/// "lin_rec709": scene-linear light, Rec.709/sRGB primaries, D65 white; Image pixels are in this space
/// unless a function says otherwise.
///
/// Which config is active (looked up again whenever the environment variables below change):
///  1. $OCIO when set and non-empty. If it cannot be loaded, every function throws
///     Error("$OCIO=<path>: <OCIO message>; unset OCIO to use envkit's built-in config").
///  2. otherwise $ENVKIT_OCIO_CONFIG when set (envkit's own override of the shipped config);
///  3. otherwise the shipped config: the installed copy (<prefix>/share/envkit/ocio/config.ocio) if it
///     exists, else the one in the source tree (libenv/data/ocio/config.ocio).
///
/// Colour-space names accept anything OCIO resolves (names, aliases, roles, case-insensitive). When a
/// user config lacks one of envkit's standard names ("lin_rec709", "srgb", "rec709", "acescg",
/// "aces2065-1", "raw"), common spellings from other configs are tried ("sRGB - Texture",
/// "ACES - ACEScg", "Utility - Raw", ...). Unknown names throw Error("unknown colour space 'x' ...; valid
/// colour spaces: a, b, c") on one line.
#include <envkit/core/image.h>
#include <envkit/core/vec.h>

#include <string>
#include <vector>

namespace envkit {

/// Canonical name of the working space (role scene_linear), e.g. "lin_rec709".
std::string working_space();

/// Where the active config came from: a file path, prefixed by "$OCIO=" when it came from $OCIO.
std::string color_config_source();

/// Names of the active colour spaces of the config (scene- and display-referred), in config order.
std::vector<std::string> colorspace_names();

/// The config's canonical name for `name` (alias, role or name in any case); throws Error for unknown names.
std::string canonical_colorspace(const std::string& name);

/// True if `name` is a data space (never converted: "raw").
bool is_data_colorspace(const std::string& name);

/// Converts the colour channels of `image` in place from colour space `from` to `to` (default: the working
/// space). Alpha is left untouched. Layouts: Y and YA (a grey value is converted as (Y, Y, Y) and the result
/// reduced with the config's luma weights), RGB and RGBA; other layouts throw Error. Rows are processed in
/// parallel (TBB). Values the transform cannot represent (float overflow) are clamped to +/-FLT_MAX and
/// NaN results become 0, so no non-finite value leaves this function for finite input.
void convert_colorspace(Image& image, const std::string& from, const std::string& to = "scene_linear");

/// Decodes a pure power-law encoding in place: colour = encoded^gamma (negative inputs map to 0), alpha
/// untouched. For files tagged with a bare gamma (PNG gAMA, OIIO "GammaCorrected"); the primaries are
/// assumed to be the working space's.
void decode_gamma(Image& image, double gamma);

/// Relative luminance weights (the Y row of the space's RGB -> CIE XYZ, as seen from the working space,
/// i.e. after the config's chromatic adaptation) of linear colour space `colorspace`. For lin_rec709:
/// (0.2126, 0.7152, 0.0722). Computed as luma_working . M(colorspace -> working), with luma_working the
/// config's default luma coefficients. Throws Error for data spaces.
Vec3 luminance_weights(const std::string& colorspace = "scene_linear");

/// Names of the active displays and of the views of one display.
std::vector<std::string> display_names();
std::vector<std::string> view_names(const std::string& display);

/// Converts `image` (working space) in place to display-referred values for `display`/`view` through the
/// config's display/view transform, clamped to [0, 1] (ready for 8-bit quantisation). Alpha untouched.
/// The shipped config has display "sRGB" with views "Standard" (no tone mapping, clips above 1),
/// "ACES 1.0 - SDR Video" (tone-mapped) and "Raw". Unknown display/view: Error listing the valid ones.
void encode_for_display(Image& image, const std::string& display = "sRGB", const std::string& view = "Standard");

}  // namespace envkit
