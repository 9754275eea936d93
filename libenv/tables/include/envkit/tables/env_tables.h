#pragma once
/// @file env_tables.h
/// Baked sampling tables of an environment map: the scalar importance map and the distributions built from it
/// (cdf, alias, hierarchical, and optionally their MIS-compensated twins), in memory and in versioned files.
///
/// Baking (EnvTables::bake):
///  1. The map is brought onto the bake grid: an envkit-canonical lat-long (centre-sampled, +Y up), equal-area
///     octahedral or HEALPix (healpix.h's 4x3 layout) map of the requested size. A map already on that grid with an
///     identity map->world transform is used as is; anything else (other parameterizations, conventions, rotations,
///     sizes) is resampled with the flux-conserving `area` filter. Directions in the tables are therefore in the map's
///     WORLD frame.
///  2. importance(x, y) = luminance (weights from the map's colour space through OCIO, Rec.709 when unknown),
///     average or max of the colour channels, negative and NaN treated as 0. Optional --resolution: the scalar
///     importance is area-filtered down to W x H (solid-angle weighted). Optional conservative mode: each texel
///     takes the max of its 3x3 neighbourhood (its bilinear lookup footprint; longitude wraps, edges fold).
///  3. Weights = importance x exact texel solid angle (lat-long: (2 pi / W)(cos theta0 - cos theta1)), computed in
///     double and stored as float. When they would leave float's comfortable range (their sum above 2^120, or a
///     positive weight below 2^-120: importance near float's subnormal range or near FLT_MAX), all of them are
///     first scaled by one power of two that brings them back as far as the sum allows, so that no weight of a lit
///     texel rounds to 0 and no sum overflows; the pdf of a constant map is 1 / (4 pi) at every scale. Maps within
///     that range (every real map) keep their weights in absolute units, bit for bit.
///  4. Compensated (Karlik et al. 2019): importance' = max(importance - mean, 0), mean = the solid-angle mean over
///     the sphere. When that is zero everywhere (a constant map) the compensated table falls back to the plain
///     importance, and says so in warnings().
///
/// File format ("ENVKTBL", see docs/TABLE_FORMAT.md): a fixed header (magic, version, section count), a JSON
/// descriptor section (parameterization, sizes, importance mode, bake settings, source path and content hash),
/// then binary sections (importance map, each distribution's arrays) at 64-byte aligned offsets, each with its
/// size and checksum in the directory (XXH3-64 over the XXH3-64 digests of its 16 MiB blocks, so verification
/// runs in parallel). Loading maps the file (mmap), verifies every checksum and uses the arrays in place (zero
/// copy, no per-element parsing; alias indices get one bounds pass). Loaded and freshly baked tables give
/// bit-identical samples.
#include <envkit/core/image.h>
#include <envkit/core/table_blob.h>
#include <envkit/maps/parameterization.h>
#include <envkit/sampling/env_sampling.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace envkit {

struct EnvMap;
class SunSplit;

/// A table: a spherical distribution over a 2D distribution that table files store (cdf, alias, hierarchical or
/// sparse). What EnvTables and SunSplit hold and save.
class StoredTable : public SphericalDistribution {
 public:
  /// See SphericalDistribution's constructors.
  StoredTable(Kind grid, std::shared_ptr<const StoredDistribution2D> distribution)
      : SphericalDistribution(grid, distribution), stored_(std::move(distribution)) {}
  StoredTable(const SphericalDistribution& same_grid, std::shared_ptr<const StoredDistribution2D> distribution)
      : SphericalDistribution(same_grid, distribution), stored_(std::move(distribution)) {}

  /// distribution(), as the table file stores it.
  const StoredDistribution2D& stored() const { return *stored_; }
  std::shared_ptr<const StoredDistribution2D> stored_ptr() const { return stored_; }

 private:
  std::shared_ptr<const StoredDistribution2D> stored_;
};

/// How a texel's colour becomes one scalar.
enum class ImportanceMode { Luminance, Average, Max };
const char* importance_name(ImportanceMode mode);
ImportanceMode parse_importance(const std::string& name);  ///< throws Error for an unknown name

/// Format version written by this build; files with another version are refused.
inline constexpr std::uint32_t kTableFormatVersion = 2;

struct BakeOptions {
  ImportanceMode importance = ImportanceMode::Luminance;
  Kind grid = Kind::LatLong;  ///< LatLong, Octahedral or HEALPix
  /// Bake grid size, texels. 0 = natural: the source's size when it is already on the grid, else a grid with
  /// about as many texels as the source (lat-long 2N x N, octahedral N x N, HEALPix 4 N_side x 3 N_side).
  /// Octahedral must be square, HEALPix 4 N_side x 3 N_side (Error otherwise).
  int width = 0;
  int height = 0;
  /// Importance resolution (--resolution); 0 = the bake grid size. Must not exceed it.
  int importance_width = 0;
  int importance_height = 0;
  bool cdf = true;
  bool alias = true;
  bool hierarchical = true;
  bool compensated = false;  ///< also build the compensated twin of every requested method
  /// Also look for the map's sun (sun.h, default SunOptions) and, when there is one, store the sun split
  /// (sun_split.h) of every table: a renderer then loads it instead of building it.
  bool sun = false;
  bool conservative = false;
  std::function<void(double fraction, const char* stage)> progress;  ///< optional, from the calling thread
};

/// Sets which tables a bake builds from their names, as envbake's --tables and Python's bake(tables=...) take them:
/// the methods ("cdf", "alias", "hierarchical", also spelled "pyramid"), "compensated" and "sun". The others are
/// cleared. Throws Error("unknown table '...' (cdf, alias, hierarchical, compensated, sun)") for another name and
/// Error("name at least one of cdf, alias, hierarchical") when no method is named.
void select_tables(const std::vector<std::string>& names, BakeOptions& options);

/// Content hash of an image (size, channel names and pixel bytes): XXH3-128 as 32 hex digits. Used for maps
/// that exist only in memory.
std::string image_content_hash(const Image& image);
/// Content hash of source files (their bytes, in order; six faces for a cube pattern): XXH3-128 as 32 hex
/// digits. This is the hash tools record and check: independent of how the file is decoded.
/// Throws Error naming a file that cannot be read.
std::string file_content_hash(const std::vector<std::string>& paths);

/// The name of one baked table: the method's name, "-compensated" appended for its MIS-compensated twin
/// ("cdf", "hierarchical-compensated"). The one spelling of table files' sections, table_bytes(), envinfo and
/// Python's Tables.methods().
std::string table_name(SamplingMethod method, bool compensated);

/// A warning of a bake: its cause, typed, and the message tools print. A table file stores the messages only; the
/// causes of loaded tables are those a bake of them finds (the conditions show in the tables themselves).
struct TableWarning {
  enum class Cause {
    NoLight,              ///< the map carries no light: the tables sample uniformly
    ZeroRows,             ///< all-zero rows are never sampled
    UnreachableTexels,    ///< lit texels below the float resolution of their CDF (cdf gives them pdf 0)
    CompensatedFallback,  ///< the compensated importance is zero everywhere: the compensated tables are the plain ones
    Other,                ///< a stored warning these causes do not account for (a file edited by hand)
  };
  Cause cause = Cause::Other;
  std::string message;

  /// Whether it concerns the compensated tables only: a renderer that does not draw from them need not say it.
  bool concerns_compensated_tables() const { return cause == Cause::CompensatedFallback; }
};

class EnvTables {
 public:
  /// Bakes tables from an environment map. source_path and source_hash are recorded (hash computed when empty).
  static EnvTables bake(const EnvMap& map, const BakeOptions& options, const std::string& source_path = "",
                        std::string source_hash = "");
  /// Loads a table file. Throws Error naming the file and the problem: not a table file, wrong version, truncated,
  /// checksum mismatch, or (when expected_source_hash is not empty) a stale table whose source hash differs.
  static EnvTables load(const std::string& path, const std::string& expected_source_hash = "");
  /// Writes atomically (temporary file + rename).
  void save(const std::string& path) const;

  /// The distribution of a method, or nullptr when it was not baked.
  const StoredTable* distribution(SamplingMethod method, bool compensated = false) const;
  /// The sun split of that distribution as a bake with BakeOptions::sun stored it: nullopt when none was stored for
  /// it (SunSplit::make builds one), a null pointer when the bake found no sun in the map.
  std::optional<std::shared_ptr<const SunSplit>> stored_sun_split(SamplingMethod method, bool compensated) const;

  Kind grid() const { return grid_; }
  /// Size of the distributions (the importance resolution).
  int width() const { return width_; }
  int height() const { return height_; }
  /// Size of the bake grid the radiance was brought onto before an optional --resolution reduction: the grid a
  /// renderer should look radiance up on (equal to width() x height() without --resolution).
  int grid_width() const { return grid_width_; }
  int grid_height() const { return grid_height_; }
  ImportanceMode importance_mode() const { return mode_; }
  bool conservative() const { return conservative_; }
  /// Scalar importance per texel of the distribution grid (radiance-like, per steradian), row-major.
  std::span<const float> importance() const { return {importance_.data(), importance_.size()}; }
  /// Total power of the importance: sum(importance x Omega), in double.
  double total_importance() const { return total_importance_; }
  const std::string& source_path() const { return source_path_; }
  const std::string& source_hash() const { return source_hash_; }
  /// The source map's map->world transform (its convention and rotation) when it was baked: the tables hold
  /// directions in that world frame, so they fit a map only when its to_world() is the same. Empty for files
  /// written before this was recorded.
  const std::optional<Mat3>& source_to_world() const { return source_to_world_; }
  /// The table file these tables were loaded from; empty for tables baked in memory. For error messages.
  const std::string& file_path() const { return file_path_; }
  /// The descriptor as stored (JSON text): bake settings, sizes, methods, warnings.
  const std::string& descriptor() const { return descriptor_; }
  /// Warnings of the bake (all-zero map, zero rows, unreachable texels, compensated fallback).
  const std::vector<TableWarning>& warnings() const { return warnings_; }
  /// Bytes held by each table kind, by name ("importance", "cdf", "alias", "hierarchical", "cdf-compensated", ...).
  std::vector<std::pair<std::string, std::size_t>> table_bytes() const;

 private:
  EnvTables() = default;
  void build_distributions(const BakeOptions& options);
  /// Finds the map's sun once and stores the split of every distribution (BakeOptions::sun).
  void store_sun_splits();
  std::string make_descriptor(const BakeOptions* options) const;
  /// The warnings a bake of these tables gives, in the order it gives them (`compensated`: it made compensated
  /// tables).
  std::vector<TableWarning> bake_warnings(bool compensated) const;
  /// No texel's importance is above its solid-angle mean: the compensated importance max(f - mean, 0) is zero.
  bool compensated_importance_is_zero() const;
  /// Stored warning messages with the causes bake_warnings() finds for them (Other when they do not match).
  std::vector<TableWarning> with_causes(const std::vector<std::string>& messages) const;

  Kind grid_ = Kind::LatLong;
  int width_ = 0;
  int height_ = 0;
  int grid_width_ = 0;
  int grid_height_ = 0;
  ImportanceMode mode_ = ImportanceMode::Luminance;
  bool conservative_ = false;
  TableArray<float> importance_;
  double total_importance_ = 0.0;
  std::string source_path_;
  std::string source_hash_;
  std::optional<Mat3> source_to_world_;
  std::string file_path_;
  std::string descriptor_;
  std::vector<TableWarning> warnings_;
  // [compensated][method]
  std::array<std::array<std::unique_ptr<StoredTable>, 3>, 2> distributions_;
  bool sun_looked_for_ = false;  // BakeOptions::sun; the splits below are null when the map has no sun
  std::array<std::array<std::shared_ptr<const SunSplit>, 3>, 2> sun_splits_;
};

/// The table of `method` over a bake grid (kind, width, height as EnvTables::grid(), width(), height()) from
/// per-texel importance (radiance-like, per steradian; row-major, width x height values): weights = importance x
/// exact texel solid angle, the same weights a bake builds. For tables of importance derived from a bake's, such as
/// sun_split.h's. Throws Error for a size that does not fit the grid.
std::unique_ptr<StoredTable> make_table(Kind grid, int width, int height, std::span<const float> importance,
                                        SamplingMethod method);

/// The sections of a table file held in memory (name, byte offset and size of each payload), read from its
/// directory without verifying anything. Empty when `file` is too short or has no envkit table header.
/// For tools and tests that patch values inside a file (the table fuzzer does) together with reseal_table_file().
struct TableFileSection {
  std::string name;
  std::size_t offset = 0;
  std::size_t size = 0;
};
std::vector<TableFileSection> table_file_sections(const std::vector<std::byte>& file);

/// Recomputes every section checksum and the directory checksum of a table file held in memory, so that
/// EnvTables::load judges its values rather than rejecting it on a checksum. Entries pointing outside `file` are
/// left as they are.
void reseal_table_file(std::vector<std::byte>& file);

}  // namespace envkit
