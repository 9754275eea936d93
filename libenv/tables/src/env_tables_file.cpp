// The table file format (docs/TABLE_FORMAT.md): save and load of EnvTables.
//
//   offset 0   FileHeader (64 bytes): magic "ENVKTBL\0", version, byte-order mark, section count, header checksum
//   offset 64  section_count x SectionEntry (64 bytes each): name, offset, size, XXH3-64 checksum
//   then       sections, each starting at a multiple of 64 bytes
// Sections: "descriptor" (JSON text), "importance" (blob: float array W x H), then one blob per distribution:
// "cdf", "alias", "hierarchical" and their "-compensated" twins; with a stored sun split, "sun" (a flag, then the sun)
// and the residual table of each distribution as "sun-<its section name>".
#include <envkit/core/atomic_file.h>
#include <envkit/core/input_checks.h>
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/tables/env_tables.h>
#include <envkit/tables/sun_split.h>
#include <tbb/parallel_for.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#define XXH_INLINE_ALL
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <deque>
#include <fstream>
#include <memory>
#include <new>
#include <utility>

namespace envkit {

namespace {

constexpr char kMagic[8] = {'E', 'N', 'V', 'K', 'T', 'B', 'L', '\0'};
constexpr std::uint32_t kByteOrderMark = 0x01020304u;
constexpr std::uint32_t kMaxSections = 64;

struct FileHeader {
  char magic[8];
  std::uint32_t version;
  std::uint32_t byte_order;
  std::uint32_t section_count;
  std::uint32_t reserved0;
  std::uint64_t directory_checksum;  // XXH3-64 of the section entries
  std::uint64_t reserved[4];
};
static_assert(sizeof(FileHeader) == 64);

struct SectionEntry {
  char name[32];
  std::uint64_t offset;
  std::uint64_t size;
  std::uint64_t checksum;  // XXH3-64 of the section bytes
};
static_assert(sizeof(SectionEntry) == 56);
constexpr std::size_t kEntryBytes = 64;  // entries are padded to 64 bytes

std::size_t align64(std::size_t n) { return (n + 63) & ~std::size_t(63); }

/// Section checksum: XXH3-64 of the XXH3-64 digests of its 16 MiB blocks (blocks hashed in parallel on load).
constexpr std::size_t kChecksumBlock = std::size_t(16) << 20;

/// The same checksum over a blob's pieces, streamed block by block (no contiguous copy needed).
std::uint64_t section_checksum(const BlobWriter& blob) {
  std::vector<std::uint64_t> digests;
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  std::size_t in_block = 0;
  for (const BlobWriter::Piece& piece : blob.pieces()) {
    for (std::size_t offset = 0; offset < piece.size;) {
      const std::size_t n = std::min(piece.size - offset, kChecksumBlock - in_block);
      XXH3_64bits_update(state, piece.data + offset, n);
      offset += n;
      in_block += n;
      if (in_block == kChecksumBlock) {
        digests.push_back(XXH3_64bits_digest(state));
        XXH3_64bits_reset(state);
        in_block = 0;
      }
    }
  }
  if (in_block > 0 || digests.empty()) digests.push_back(XXH3_64bits_digest(state));
  XXH3_freeState(state);
  return XXH3_64bits(digests.data(), digests.size() * sizeof(std::uint64_t));
}
std::uint64_t section_checksum(const std::byte* data, std::size_t size) {
  const std::size_t blocks = std::max<std::size_t>(1, (size + kChecksumBlock - 1) / kChecksumBlock);
  std::vector<std::uint64_t> digests(blocks);
  tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
    const std::size_t begin = b * kChecksumBlock;
    digests[b] = XXH3_64bits(data + begin, std::min(kChecksumBlock, size - std::min(size, begin)));
  });
  return XXH3_64bits(digests.data(), digests.size() * sizeof(std::uint64_t));
}

struct Section {
  std::string name;
  BlobWriter blob;
};

/// The bytes of a whole file, read-only. Files of kMapFrom bytes or more are memory-mapped (read in one pass,
/// pages shared with the page cache); smaller ones are read into a buffer: a mapping costs a VMA and, when it goes,
/// a TLB flush on every core that ran the process, more than reading a few pages (a session or a batch that loads
/// many small table files).
class FileBytes {
 public:
  static constexpr std::size_t kMapFrom = std::size_t(1) << 20;
  static constexpr std::align_val_t kAlignment{64};  // sections start at multiples of 64 bytes of the file

  explicit FileBytes(const std::string& path) {
    if (std::filesystem::exists(path)) require_regular_file(path);  // open() would block on a FIFO
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw Error(path + ": cannot open: " + std::strerror(errno));
    try {
      struct stat st {};
      if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) throw Error(path + ": not a regular file");
      size_ = static_cast<std::size_t>(st.st_size);
      if (size_ >= kMapFrom)
        map(fd, path);
      else if (size_ > 0)
        read_all(fd, path);
    } catch (...) {
      ::close(fd);
      throw;
    }
    ::close(fd);
  }
  ~FileBytes() {
    if (mapped_) ::munmap(const_cast<std::byte*>(data_), size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;
  const std::byte* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  void map(int fd, const std::string& path) {
    // MAP_POPULATE reads the pages in up front (one pass, no page fault per 4 KiB later).
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (p == MAP_FAILED) throw Error(path + ": cannot map: " + std::strerror(errno));
    data_ = static_cast<const std::byte*>(p);
    mapped_ = true;
  }
  void read_all(int fd, const std::string& path) {
    buffer_.reset(static_cast<std::byte*>(::operator new(size_, kAlignment)));
    data_ = buffer_.get();
    for (std::size_t done = 0; done < size_;) {
      const ssize_t n = ::read(fd, buffer_.get() + done, size_ - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw Error(path + ": cannot read: " + std::strerror(errno));
      if (n == 0) throw Error(path + ": cannot read: the file shrank while being read");
      done += static_cast<std::size_t>(n);
    }
  }

  struct AlignedDelete {
    void operator()(std::byte* p) const { ::operator delete(p, kAlignment); }
  };
  std::unique_ptr<std::byte, AlignedDelete> buffer_;  // a read file (freed also when the constructor throws)
  const std::byte* data_ = nullptr;
  std::size_t size_ = 0;
  bool mapped_ = false;
};

std::string section_name(int method, int set) { return table_name(SamplingMethod(method), set != 0); }

std::shared_ptr<const StoredDistribution2D> restore_distribution(int method, BlobReader& in) {
  switch (SamplingMethod(method)) {
    case SamplingMethod::Cdf:
      return std::make_shared<CdfDistribution2D>(in);
    case SamplingMethod::Alias:
      return std::make_shared<AliasDistribution2D>(in);
    case SamplingMethod::Hierarchical:
      return std::make_shared<HierarchicalDistribution2D>(in);
  }
  throw Error(in.context() + ": unknown method");
}

}  // namespace

void EnvTables::save(const std::string& path) const {
  // Sections reference the tables' own memory: nothing is copied before it is written.
  std::deque<Section> sections;
  sections.push_back({"descriptor", {}});
  sections.back().blob.raw(descriptor_.data(), descriptor_.size());
  sections.push_back({"importance", {}});
  sections.back().blob.array(importance_);
  for (int set = 0; set < 2; ++set)
    for (int m = 0; m < 3; ++m)
      if (distributions_[set][m]) {
        sections.push_back({section_name(m, set), {}});
        distributions_[set][m]->stored().save(sections.back().blob);
      }
  if (sun_looked_for_) {
    sections.push_back({"sun", {}});
    const SunSplit* sun = nullptr;
    for (int set = 0; set < 2; ++set)
      for (int m = 0; m < 3; ++m)
        if (sun_splits_[set][m]) {
          sun = sun_splits_[set][m].get();
          sections.push_back({"sun-" + section_name(m, set), {}});
          sun->residual().stored().save(sections.back().blob);
        }
    Section& found = *std::find_if(sections.begin(), sections.end(), [](const Section& s) { return s.name == "sun"; });
    found.blob.scalar<std::uint64_t>(sun ? 1 : 0);
    if (sun) sun->save_sun(found.blob);
  }

  FileHeader header{};
  std::memcpy(header.magic, kMagic, sizeof(kMagic));
  header.version = kTableFormatVersion;
  header.byte_order = kByteOrderMark;
  header.section_count = static_cast<std::uint32_t>(sections.size());
  std::vector<std::byte> directory(sections.size() * kEntryBytes, std::byte{0});
  std::size_t offset = align64(sizeof(FileHeader) + directory.size());
  for (std::size_t i = 0; i < sections.size(); ++i) {
    SectionEntry e{};
    std::strncpy(e.name, sections[i].name.c_str(), sizeof(e.name) - 1);
    e.offset = offset;
    e.size = sections[i].blob.size();
    e.checksum = section_checksum(sections[i].blob);
    std::memcpy(directory.data() + i * kEntryBytes, &e, sizeof(e));
    offset = align64(offset + sections[i].blob.size());
  }
  header.directory_checksum = XXH3_64bits(directory.data(), directory.size());

  AtomicOutput out(path);
  {
    AtomicOutputStream f(out);
    static const char zeros[64] = {};
    std::size_t written = 0;
    const auto put = [&](const void* data, std::size_t n) {
      f.write(static_cast<const char*>(data), std::streamsize(n));
      written += n;
    };
    const auto pad = [&] { put(zeros, align64(written) - written); };
    put(&header, sizeof(header));
    put(directory.data(), directory.size());
    for (const Section& s : sections) {
      pad();
      for (const BlobWriter::Piece& piece : s.blob.pieces()) put(piece.data, piece.size);
    }
    pad();
    f.close();
  }
  out.commit();
}

EnvTables EnvTables::load(const std::string& path, const std::string& expected_source_hash) {
  const auto file = std::make_shared<const FileBytes>(path);  // kept alive by the tables that view it
  const std::byte* data = file->data();
  const std::size_t size = file->size();
  const auto fail_with = [&](const std::string& problem) { return Error(path + ": " + problem); };

  if (size < sizeof(FileHeader)) throw fail_with("not an envkit table file (too short)");
  FileHeader header;
  std::memcpy(&header, data, sizeof(header));
  if (std::memcmp(header.magic, kMagic, sizeof(kMagic)) != 0) throw fail_with("not an envkit table file (bad magic)");
  if (header.byte_order != kByteOrderMark) throw fail_with("written on a machine of the other byte order");
  if (header.version != kTableFormatVersion)
    throw fail_with("table format version " + std::to_string(header.version) + " is not supported (this build reads " +
                    std::to_string(kTableFormatVersion) + "; re-bake with envbake)");
  if (header.section_count == 0 || header.section_count > kMaxSections)
    throw fail_with("corrupt header (" + std::to_string(header.section_count) + " sections)");
  const std::size_t directory_bytes = header.section_count * kEntryBytes;
  if (size < sizeof(FileHeader) + directory_bytes) throw fail_with("truncated (section directory)");
  if (XXH3_64bits(data + sizeof(FileHeader), directory_bytes) != header.directory_checksum)
    throw fail_with("checksum mismatch in the section directory (corrupt file)");

  std::map<std::string, std::pair<const std::byte*, std::size_t>> sections;
  for (std::uint32_t i = 0; i < header.section_count; ++i) {
    SectionEntry e;
    std::memcpy(&e, data + sizeof(FileHeader) + i * kEntryBytes, sizeof(e));
    e.name[sizeof(e.name) - 1] = '\0';
    const std::string name = e.name;
    if (e.offset > size || e.size > size - e.offset)
      throw fail_with("truncated (section '" + name + "' runs past the end of the file)");
    if (section_checksum(data + e.offset, e.size) != e.checksum)
      throw fail_with("checksum mismatch in section '" + name + "' (corrupt file)");
    sections[name] = {data + e.offset, static_cast<std::size_t>(e.size)};
  }
  const auto section = [&](const std::string& name) {
    const auto it = sections.find(name);
    if (it == sections.end()) throw fail_with("missing section '" + name + "'");
    return it->second;
  };

  EnvTables t;
  t.file_path_ = path;
  const auto [descriptor_data, descriptor_size] = section("descriptor");
  t.descriptor_.assign(reinterpret_cast<const char*>(descriptor_data), descriptor_size);
  std::vector<std::string> warning_messages;
  try {
    const nlohmann::json d = nlohmann::json::parse(t.descriptor_);
    t.grid_ = parse_kind(d.at("grid").get<std::string>());
    t.width_ = d.at("width").get<int>();
    t.height_ = d.at("height").get<int>();
    t.grid_width_ = d.at("grid_width").get<int>();
    t.grid_height_ = d.at("grid_height").get<int>();
    t.mode_ = parse_importance(d.at("importance").get<std::string>());
    t.conservative_ = d.at("conservative").get<bool>();
    t.total_importance_ = d.at("total_importance").get<double>();
    t.source_path_ = d.at("source").at("path").get<std::string>();
    t.source_hash_ = d.at("source").at("hash").get<std::string>();
    if (d.at("source").contains("to_world")) {
      const auto m = d.at("source").at("to_world").get<std::vector<double>>();
      if (m.size() != 9 || !std::all_of(m.begin(), m.end(), [](double v) { return std::isfinite(v); }))
        throw Error("source.to_world is not 9 finite numbers");
      t.source_to_world_ = Mat3(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]);
    }
    warning_messages = d.at("warnings").get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    throw fail_with(std::string("corrupt descriptor: ") + e.what());
  } catch (const Error& e) {
    throw fail_with(std::string("corrupt descriptor: ") + e.what());
  }
  // Sizes a grid cannot have are refused here with the file's name, not later by SphericalDistribution.
  const auto grid_shape_ok = [&](int w, int h) {
    if (t.grid_ == Kind::HEALPix) return w % 4 == 0 && std::int64_t(w) * 3 == std::int64_t(h) * 4;
    return t.grid_ != Kind::Octahedral || w == h;
  };
  if ((t.grid_ != Kind::LatLong && t.grid_ != Kind::Octahedral && t.grid_ != Kind::HEALPix) || t.width_ < 1 ||
      t.height_ < 1 || !grid_shape_ok(t.width_, t.height_) || !grid_shape_ok(t.grid_width_, t.grid_height_) ||
      t.width_ > kMaxDistributionSize || t.height_ > kMaxDistributionSize || t.grid_width_ < t.width_ ||
      t.grid_height_ < t.height_ || t.grid_width_ > kMaxDistributionSize || t.grid_height_ > kMaxDistributionSize)
    throw fail_with("corrupt descriptor (grid or size)");
  if (!expected_source_hash.empty() && expected_source_hash != t.source_hash_)
    throw fail_with("stale tables: baked from a different image (source hash " + t.source_hash_ + ", image hash " +
                    expected_source_hash + "); re-bake with envbake");

  const std::size_t texels = std::size_t(t.width_) * std::size_t(t.height_);
  {
    const auto [p, n] = section("importance");
    BlobReader in(p, n, path + ": section importance", file);
    t.importance_ = in.table<float>(texels);
    in.finish();
    // Values, not only bytes: the importance feeds the compensated tables and tools' exports.
    const auto& importance = std::as_const(t.importance_);
    if (!std::all_of(importance.begin(), importance.end(), [](float v) { return v >= 0.0f && v <= FLT_MAX; }))
      throw fail_with("section importance: invalid values (not finite and >= 0)");
  }
  if (!(t.total_importance_ >= 0.0 && std::isfinite(t.total_importance_)))
    throw fail_with("corrupt descriptor (total importance)");
  // Every distribution of the file lies on one grid: the first computes its geometry, the others share it.
  const SphericalDistribution* first = nullptr;
  const auto restore_on_grid = [&](int m, BlobReader& in, const std::string& name) {
    std::shared_ptr<const StoredDistribution2D> d = restore_distribution(m, in);
    if (d->width() != t.width_ || d->height() != t.height_)
      throw fail_with("section " + name + " does not match the descriptor's size");
    return first ? std::make_unique<StoredTable>(*first, std::move(d))
                 : std::make_unique<StoredTable>(t.grid_, std::move(d));
  };
  for (int set = 0; set < 2; ++set)
    for (int m = 0; m < 3; ++m) {
      const std::string name = section_name(m, set);
      const auto it = sections.find(name);
      if (it == sections.end()) continue;
      BlobReader in(it->second.first, it->second.second, path + ": section " + name, file);
      t.distributions_[set][m] = restore_on_grid(m, in, name);
      if (!first) first = t.distributions_[set][m].get();
    }
  t.warnings_ = t.with_causes(warning_messages);
  if (const auto sun = sections.find("sun"); sun != sections.end()) {
    // The flag, then (when set) the sun, read again for each residual table that shares it.
    const auto sun_blob = [&, sun] {
      return BlobReader(sun->second.first, sun->second.second, path + ": section sun");
    };
    BlobReader flag = sun_blob();
    const auto found = flag.scalar<std::uint64_t>();
    if (found > 1) throw fail_with("section sun: invalid flag");
    if (found == 0) flag.finish();  // nothing may follow "no sun"
    t.sun_looked_for_ = true;
    bool any = false;
    for (int set = 0; set < 2 && found; ++set)
      for (int m = 0; m < 3; ++m) {
        const std::string name = "sun-" + section_name(m, set);
        const auto it = sections.find(name);
        if (it == sections.end()) continue;
        if (!t.distributions_[set][m]) throw fail_with("section " + name + " splits a table the file does not hold");
        BlobReader residual_in(it->second.first, it->second.second, path + ": section " + name, file);
        std::shared_ptr<const StoredTable> residual = restore_on_grid(m, residual_in, name);
        BlobReader sun_in = sun_blob();
        sun_in.scalar<std::uint64_t>();
        t.sun_splits_[set][m] =
            std::make_shared<const SunSplit>(SunSplit::restore(sun_in, t.grid_, t.width_, t.height_, residual));
        any = true;
      }
    if (found && !any) throw fail_with("section sun: a sun without any residual table");
  }
  return t;
}

std::vector<TableFileSection> table_file_sections(const std::vector<std::byte>& file) {
  std::vector<TableFileSection> out;
  if (file.size() < sizeof(FileHeader)) return out;
  FileHeader header;
  std::memcpy(&header, file.data(), sizeof(header));
  if (std::memcmp(header.magic, kMagic, sizeof(kMagic)) != 0 || header.section_count > kMaxSections ||
      file.size() < sizeof(FileHeader) + header.section_count * kEntryBytes)
    return out;
  for (std::uint32_t i = 0; i < header.section_count; ++i) {
    SectionEntry e;
    std::memcpy(&e, file.data() + sizeof(FileHeader) + i * kEntryBytes, sizeof(e));
    e.name[sizeof(e.name) - 1] = '\0';
    out.push_back({e.name, static_cast<std::size_t>(e.offset), static_cast<std::size_t>(e.size)});
  }
  return out;
}

void reseal_table_file(std::vector<std::byte>& file) {
  const std::vector<TableFileSection> sections = table_file_sections(file);
  if (sections.empty()) return;
  for (std::size_t i = 0; i < sections.size(); ++i) {
    const TableFileSection& s = sections[i];
    if (s.offset > file.size() || s.size > file.size() - s.offset) continue;
    SectionEntry e;
    std::byte* entry = file.data() + sizeof(FileHeader) + i * kEntryBytes;
    std::memcpy(&e, entry, sizeof(e));
    e.checksum = section_checksum(file.data() + s.offset, s.size);
    std::memcpy(entry, &e, sizeof(e));
  }
  FileHeader header;
  std::memcpy(&header, file.data(), sizeof(header));
  header.directory_checksum = XXH3_64bits(file.data() + sizeof(FileHeader), header.section_count * kEntryBytes);
  std::memcpy(file.data(), &header, sizeof(header));
}

}  // namespace envkit
