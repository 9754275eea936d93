#include <envkit/core/error.h>
#include <envkit/ibl/dds.h>
#include <envkit/ibl/exr_cube_mips.h>
#include <envkit/ibl/ibl_files.h>
#include <envkit/io/image_io.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <sstream>

namespace envkit {

namespace {

std::string extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

std::string join_numbers(const std::vector<double>& v) {
  std::ostringstream s;
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? "," : "") << v[i];
  return s.str();
}

}  // namespace

void check_ibl_output(const std::string& path) {
  const std::string e = extension(path);
  if (e != ".ktx2" && e != ".dds" && e != ".exr") fail(path, "expected a .ktx2, .dds or .exr file");
}

bool is_exr_cube_mips_path(const std::string& path) {
  return extension(path) == ".exr" && path.find('%') == std::string::npos;
}

void set_ibl_cube_faces(const std::string& path, PrefilterOptions& options) {
  const bool exr = is_exr_cube_mips_path(path);
  options.cube_basis = exr ? CubeBasis::Envkit : CubeBasis::GL;
  options.cube_grid = exr ? TexelGrid::Corner : TexelGrid::Centre;
}

std::vector<IblFile> ggx_chain_files(const std::string& pattern, const PrefilteredChain& chain, Kind kind,
                                     const std::string& source) {
  check_ibl_output(pattern);
  PrefilterOptions faces;
  set_ibl_cube_faces(pattern, faces);
  if (kind == Kind::CubeMap && (chain.cube_basis != faces.cube_basis || chain.cube_grid != faces.cube_grid))
    fail(pattern, is_exr_cube_mips_path(pattern)
                      ? "this chain was prefiltered into GL faces; a mip-mapped OpenEXR cube holds OpenEXR's faces: "
                        "prefilter the chain for this output path"
                      : "this chain was prefiltered into OpenEXR's faces; KTX2, DDS and per-level files hold GL faces");
  const std::map<std::string, std::string> meta = {
      {"envkit:ibl_roughness_mapping", roughness_mapping_name(chain.mapping)},
      {"envkit:ibl_roughness", join_numbers(chain.roughness)},
      {"envkit:ibl_alpha", join_numbers(chain.alpha)},
      {"envkit:ibl_lobe", "GGX D(n.h) n.l, split sum n = v = r"},
      {"envkit:parameterization", kind_name(kind)},
      {"envkit:convention", "gl"},
      {"envkit:source", source}};
  if (extension(pattern) != ".exr" || is_exr_cube_mips_path(pattern)) {
    IblFile f{pattern, {}, meta};
    for (const EnvMap& l : chain.levels) f.levels.push_back(&l.image);
    if (is_exr_cube_mips_path(pattern)) {
      if (kind != Kind::CubeMap)
        fail(pattern, "one mip-mapped OpenEXR file holds a cube only: put '%' in the name for one file per level");
      f.exr_cube_mips = true;
      f.metadata["envkit:convention"] = "openexr";
      f.metadata["envkit:layout"] = "vstrip";
    }
    return {f};
  }
  std::vector<IblFile> files;
  const std::size_t at = pattern.find('%');
  for (std::size_t m = 0; m < chain.levels.size(); ++m) {
    IblFile f{pattern.substr(0, at) + std::to_string(m) + pattern.substr(at + 1), {&chain.levels[m].image}, meta};
    f.metadata["envkit:ibl_level"] = std::to_string(m);
    f.metadata["envkit:layout"] = "vstrip";
    files.push_back(std::move(f));
  }
  return files;
}

IblFile irradiance_file(const std::string& path, const EnvMap& irradiance, Kind kind) {
  check_ibl_output(path);
  const auto it = irradiance.image.metadata.find("envkit:ibl_irradiance");
  return IblFile{path,
                 {&irradiance.image},
                 {{"envkit:ibl_irradiance", it != irradiance.image.metadata.end() ? it->second : "E/pi"},
                  {"envkit:parameterization", kind_name(kind)},
                  {"envkit:convention", "gl"}}};
}

ClampReport write_ibl_file(const std::string& write_path, const IblFile& file, bool cube, GpuFormat format) {
  const std::string e = extension(file.path);
  if (file.exr_cube_mips) {
    ExrCubeMipsOptions eo;
    eo.attributes = file.metadata;
    return write_exr_cube_mips(write_path, file.levels, eo);
  }
  if (e == ".ktx2") {
    Ktx2Options ko;
    ko.format = format;
    ko.faces = cube ? 6 : 1;
    ko.key_values = file.metadata;
    return write_ktx2(write_path, file.levels, ko);
  }
  if (e == ".dds") {
    DdsOptions d;
    d.format = format;
    d.faces = cube ? 6 : 1;
    return write_dds(write_path, file.levels, d);
  }
  WriteOptions w;
  w.metadata = file.metadata;
  return write_image(write_path, *file.levels.at(0), w);
}

}  // namespace envkit
