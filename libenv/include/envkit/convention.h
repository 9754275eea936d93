#pragma once
/// @file convention.h
/// Orientation conventions: how the maps written for (or read from) other tools relate to the canonical
/// envkit world frame (right-handed, +Y up; see vec.h).
///
/// Each parameterization computes directions in its own map frame (see its header). A convention says, per
/// kind, which matrix takes those map-frame directions into the canonical world (`frame(kind)`), and which
/// texel grid, cube face basis and default cube layout the other tool uses.
///
/// | name       | lat-long                        | cube                                   | ball / angular        |
/// |------------|---------------------------------|----------------------------------------|-----------------------|
/// | envkit     | centre-sampled, centre sees +Z  | centre-sampled, envkit basis, vstrip   | centre sees +Z        |
/// | openexr    | corner-sampled (ImfEnvmap)      | corner-sampled, OpenEXR basis, N x 6N  | as envkit             |
/// | hdrshop    | as envkit (Debevec's frame)     | centre-sampled, vertical cross         | Debevec formula (+Z)  |
/// | angmap-cal | as envkit                       | as envkit                              | centre sees -Z        |
/// | blender    | Z up: centre sees +X_b, u=1/4 +Y_b | as its lat-long frame               | ball as Cycles: centre +Y_b |
/// | gl         | as envkit                       | GL face table, centre-sampled, faces   | as envkit             |
///
/// Blender's world maps to envkit's as Blender (x, y, z) = envkit (x, -z, y) (the axis change Blender's
/// glTF/OBJ importers apply), so an envkit scene imported into Blender and a map written with the blender
/// convention line up.
#include <envkit/cubemap.h>
#include <envkit/parameterization.h>

#include <string>
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
  Mat3 frames[6];

  const Mat3& frame(Kind kind) const { return frames[static_cast<int>(kind)]; }
};

/// Looks up a preset by name ("envkit", "openexr", "hdrshop", "angmap-cal", "blender", "gl"); throws Error.
const Convention& convention(const std::string& name);
std::vector<std::string> convention_names();

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
