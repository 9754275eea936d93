#include <envkit/io/oiio_env_tags.h>
#include <envkit/maps/convention.h>

#include <cstdlib>

namespace envkit {

namespace {

constexpr const char* kUpDirection = "oiio:updirection";
constexpr const char* kSampleBorder = "oiio:sampleborder";

bool close_to(const Mat3& a, const Mat3& b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (std::abs(a[i][j] - b[i][j]) > 1e-9) return false;
  return true;
}

}  // namespace

std::optional<OiioEnvReading> read_oiio_env_tags(const std::map<std::string, std::string>& metadata) {
  const auto up = metadata.find(kUpDirection);
  const auto border = metadata.find(kSampleBorder);
  if (up == metadata.end() && border == metadata.end()) return std::nullopt;
  OiioEnvReading r;
  const std::string direction = up == metadata.end() ? "y" : up->second;
  if (direction != "y" && direction != "z") return std::nullopt;
  // OIIO reads the border with get_int_attribute: any nonzero integer turns it on.
  const bool sample_border = border != metadata.end() && std::atoi(border->second.c_str()) != 0;
  if (direction == "y")
    r.convention = sample_border ? "openexr" : "envkit";
  else
    r.convention = "renderman";
  if (border != metadata.end()) {
    const TexelGrid grid = sample_border ? TexelGrid::Corner : TexelGrid::Centre;
    const Convention& conv = convention(r.convention);
    if (conv.latlong_grid != grid || conv.cube_grid != grid) r.grid = grid;
  }
  if (up != metadata.end()) r.reason = std::string(kUpDirection) + "=" + up->second;
  if (border != metadata.end())
    r.reason += (r.reason.empty() ? "" : ", ") + std::string(kSampleBorder) + "=" + border->second;
  return r;
}

std::map<std::string, std::string> oiio_env_tags_for(const Parameterization& param, const Mat3& to_world) {
  std::map<std::string, std::string> tags;
  // OIIO's environment tags describe lat-long and cube maps only.
  if (param.kind() != Kind::LatLong && param.kind() != Kind::CubeMap) return tags;
  if (param.grid() == TexelGrid::Centre || param.grid() == TexelGrid::Corner)
    tags[kSampleBorder] = param.grid() == TexelGrid::Corner ? "1" : "0";
  if (param.kind() == Kind::LatLong) {
    if (close_to(to_world, identity3()))
      tags[kUpDirection] = "y";
    else if (close_to(to_world, convention("renderman").frame(Kind::LatLong)))
      tags[kUpDirection] = "z";
  }
  return tags;
}

bool is_oiio_int_tag(const std::string& key) { return key == kSampleBorder; }

}  // namespace envkit
