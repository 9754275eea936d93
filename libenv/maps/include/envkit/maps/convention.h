#pragma once
/// @file convention.h
/// Orientation conventions: how the maps written for (or read from) other tools relate to the canonical
/// envkit world frame (right-handed, +Y up; see vec.h).
///
/// Each parameterization computes directions in its own map frame (see its header). A convention says, per
/// kind, which matrix takes those map-frame directions into the canonical world (`frame(kind)`), and which
/// texel grid, cube face basis and default cube layout the other tool uses.
///
/// | name       | lat-long                           | cube                                  | other kinds         |
/// |------------|------------------------------------|---------------------------------------|---------------------|
/// | envkit     | centre-sampled, centre sees +Z     | centre-sampled, envkit basis, vstrip  | centre sees +Z      |
/// | openexr    | corner-sampled (ImfEnvmap)         | corner-sampled, OpenEXR basis, N x 6N | as envkit           |
/// | hdrshop    | as envkit (Debevec's frame)        | centre-sampled, vertical cross        | Debevec (+Z)        |
/// | angmap-cal | as envkit                          | as envkit                             | ball/angular: -Z    |
/// | blender    | Z up: centre +X_b, u=1/4 +Y_b      | as its lat-long frame                 | ball: centre +Y_b   |
/// | gl         | as envkit                          | GL face table, centre-sampled, vstrip | as envkit           |
/// | threejs    | centre sees +X, u=3/4 +Z           | GL faces read with x mirrored         | as its lat-long     |
/// | directx    | as envkit                          | GL table, D3D world (z negated)       | as envkit           |
/// | unity      | centre sees -X, u=3/4 -Z           | GL faces, x negated, hstrip           | as envkit           |
/// | mitsuba    | as envkit, rows corner-sampled     | as envkit                             | as envkit           |
/// | pbrt       | pbrt-v3: centre sees -X, u=3/4 -Z  | as envkit                             | octahedral: (x,z,y) |
/// | renderman  | OIIO z-up: centre +X, u=3/4 +Z     | GL faces in envkit (x, z, y)          | as envkit           |
///
/// Aliases (convention_aliases()): vulkan, ktx, ktx2, filament and cmgen are gl: Vulkan and KTX use the GL face
/// table and face order unchanged, and Filament's cmgen mirrors its cube (on by default) exactly so that Filament's
/// right-handed world reads it through that table unmirrored; its equirect input is envkit's orientation.
/// Left-handed peers (directx, unity, pbrt, renderman) need a reflection somewhere: which axis flips is each
/// peer's own porting convention, named in convention.cpp. pbrt's octahedral map: pbrt (x, y, z) = envkit (x, z, y).
///
/// Blender's world maps to envkit's as Blender (x, y, z) = envkit (x, -z, y) (the axis change Blender's
/// glTF/OBJ importers apply), so an envkit scene imported into Blender and a map written with the blender
/// convention line up.
#include <envkit/maps/cubemap.h>
#include <envkit/maps/parameterization.h>

#include <string>
#include <utility>
#include <vector>

namespace envkit {

struct Convention {
  std::string name;
  std::string description;
  TexelGrid latlong_grid = TexelGrid::Centre;
  TexelGrid cube_grid = TexelGrid::Centre;
  CubeBasis cube_basis = CubeBasis::Envkit;
  CubeLayout cube_layout = CubeLayout::VerticalStrip;
  /// Map-frame -> canonical world matrix per kind (index static_cast<int>(Kind)).
  Mat3 frames[kKindCount];

  const Mat3& frame(Kind kind) const { return frames[static_cast<int>(kind)]; }
};

/// Looks up a preset by name ("envkit", "openexr", "hdrshop", "angmap-cal", "blender", "gl", "threejs", "directx",
/// "unity", "mitsuba", "pbrt", "renderman") or alias; throws Error naming the presets.
const Convention& convention(const std::string& name);
/// The preset names, in table order (aliases not included).
std::vector<std::string> convention_names();
/// Other names convention() accepts, as {alias, preset}: a peer whose maps are exactly another preset's is an
/// alias of it, not a copy.
const std::vector<std::pair<std::string, std::string>>& convention_aliases();

/// Rotation from Euler angles in degrees: R = Ry(yaw) Rx(pitch) Rz(roll) (column vectors), i.e. roll about the
/// viewing axis Z first, then pitch about X, then yaw about the up axis Y. Rotating an environment by R moves
/// what was seen in direction d to direction R d.
Mat3 rotation_from_euler_degrees(double yaw, double pitch, double roll);
/// Parses "yaw,pitch,roll" (3 numbers, degrees) or a row-major 3x3 matrix (9 numbers). The matrix must be a
/// rotation (orthonormal, det +1) within 1e-4; it is re-orthonormalised. Throws Error otherwise.
Mat3 parse_rotation(const std::string& text);
/// "yaw,pitch,roll" style one-line description of a matrix (9 numbers, row-major).
std::string format_matrix(const Mat3& m);

}  // namespace envkit
