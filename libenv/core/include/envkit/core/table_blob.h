#pragma once
/// @file table_blob.h
/// Flat binary images of in-memory tables, the payload of table-file sections (env_tables.h).
///
/// A blob is a sequence of fields, each 8-byte aligned: scalars as their raw bytes, arrays as a 64-bit element
/// count followed by the raw elements. Byte order and float format are the writer's (little-endian IEEE 754 on
/// every platform envkit builds on; the table file header records it). Arrays are read without per-element
/// parsing: as views into the blob's memory when the blob has an owner (a memory-mapped table file: zero copy),
/// else with one memcpy. Every read is bounds-checked: a blob that ends early or claims more elements than it
/// holds is an Error naming the context, never an overread.
#include <envkit/core/error.h>
#include <envkit/core/huge_page_allocator.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

namespace envkit {

/// The storage of a table: either an owned vector (while building; resize/assign/data() write to it) or a
/// read-only view into memory kept alive by an owner (a mapped file). Reading code sees one const array.
template <class T>
class TableArray {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  TableArray() = default;
  TableArray(const TableArray& other) { *this = other; }
  TableArray(TableArray&& other) noexcept { *this = std::move(other); }
  TableArray& operator=(const TableArray& other) {
    if (this == &other) return *this;
    owned_ = other.owned_;
    owner_ = other.owner_;
    data_ = owner_ ? other.data_ : owned_.data();
    size_ = other.size_;
    return *this;
  }
  TableArray& operator=(TableArray&& other) noexcept {
    owned_ = std::move(other.owned_);
    owner_ = std::move(other.owner_);
    data_ = owner_ ? other.data_ : owned_.data();
    size_ = other.size_;
    other.data_ = nullptr;
    other.size_ = 0;
    return *this;
  }
  /// A read-only view of n elements at data, valid while owner lives.
  static TableArray view(std::shared_ptr<const void> owner, const T* data, std::size_t n) {
    TableArray a;
    a.owner_ = std::move(owner);
    a.data_ = data;
    a.size_ = n;
    return a;
  }

  // Building (owned storage only).
  using Storage = std::vector<T, HugePageAllocator<T>>;
  /// Takes over a built array without copying it.
  void adopt(Storage&& values) { owned_ = std::move(values), refresh(); }
  void resize(std::size_t n) { owned_.resize(n), refresh(); }
  void assign(std::size_t n, const T& value) { owned_.assign(n, value), refresh(); }
  T* data() { return owned_.data(); }
  T& operator[](std::size_t i) { return owned_[i]; }
  T* begin() { return owned_.data(); }
  T* end() { return owned_.data() + owned_.size(); }

  // Reading (either storage).
  const T* data() const { return data_; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }
  std::size_t size() const { return size_; }
  std::size_t bytes() const { return size_ * sizeof(T); }

 private:
  void refresh() {
    owner_.reset();
    data_ = owned_.data();
    size_ = owned_.size();
  }
  Storage owned_;  // large tables: huge pages (first touch is costly on VMs)
  std::shared_ptr<const void> owner_;
  const T* data_ = nullptr;
  std::size_t size_ = 0;
};

/// Builds a blob without copying its arrays: it records pieces (8-byte scalar words it owns, and references to the
/// callers' arrays), so writing an 800 MB table set costs no second copy in memory. The referenced arrays must
/// outlive the writer's use.
class BlobWriter {
 public:
  struct Piece {
    const std::byte* data;
    std::size_t size;
  };

  template <class T>
  void scalar(const T& value) {
    static_assert(std::is_trivially_copyable_v<T> && sizeof(T) <= 8);
    std::uint64_t word = 0;
    std::memcpy(&word, &value, sizeof(T));
    words_.push_back(word);  // a deque: earlier words never move
    add(reinterpret_cast<const std::byte*>(&words_.back()), 8);
  }
  template <class T, class Allocator>
  void array(const std::vector<T, Allocator>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    reference(values.data(), values.size());
  }
  template <class T>
  void array(const TableArray<T>& values) {
    reference(values.data(), values.size());
  }
  /// Raw bytes (no count, no padding): for sections that are not blobs (the JSON descriptor).
  void raw(const void* data, std::size_t size) { add(static_cast<const std::byte*>(data), size); }

  const std::vector<Piece>& pieces() const { return pieces_; }
  std::size_t size() const { return size_; }
  /// The blob as one contiguous buffer (a copy; for small blobs and tests).
  std::vector<std::byte> flatten() const {
    std::vector<std::byte> out;
    out.reserve(size_);
    for (const Piece& p : pieces_) out.insert(out.end(), p.data, p.data + p.size);
    return out;
  }

 private:
  template <class T>
  void reference(const T* data, std::size_t count) {
    scalar<std::uint64_t>(count);
    const std::size_t n = count * sizeof(T);
    add(reinterpret_cast<const std::byte*>(data), n);
    static constexpr std::byte zeros[8] = {};
    add(zeros, ((n + 7) & ~std::size_t(7)) - n);
  }
  void add(const std::byte* data, std::size_t n) {
    if (n == 0) return;
    pieces_.push_back({data, n});
    size_ += n;
  }
  std::deque<std::uint64_t> words_;
  std::vector<Piece> pieces_;
  std::size_t size_ = 0;
};

class BlobReader {
 public:
  /// context names the blob in errors, e.g. "table.envtbl: section cdf".
  /// owner (optional) keeps data alive: arrays are then returned as views into it, not copies.
  BlobReader(const std::byte* data, std::size_t size, std::string context, std::shared_ptr<const void> owner = nullptr)
      : data_(data), size_(size), context_(std::move(context)), owner_(std::move(owner)) {}

  template <class T>
  T scalar() {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    std::memcpy(&value, take(sizeof(T)), sizeof(T));
    return value;
  }
  /// An array; expected_count (when not SIZE_MAX) must match the stored count.
  template <class T>
  std::vector<T> array(std::size_t expected_count = SIZE_MAX) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto count = scalar<std::uint64_t>();
    if (expected_count != SIZE_MAX && count != expected_count)
      throw Error(context_ + ": array holds " + std::to_string(count) + " elements, expected " +
                  std::to_string(expected_count));
    if (count > (size_ - offset_) / sizeof(T)) throw Error(context_ + ": truncated (array runs past the end)");
    std::vector<T> values(static_cast<std::size_t>(count));
    if (count) std::memcpy(values.data(), take(values.size() * sizeof(T)), values.size() * sizeof(T));
    return values;
  }
  /// An array as table storage: a zero-copy view when the blob has an owner and the data is aligned for T.
  template <class T>
  TableArray<T> table(std::size_t expected_count = SIZE_MAX) {
    if (!owner_) {
      TableArray<T> a;
      std::vector<T> v = array<T>(expected_count);
      a.resize(v.size());
      if (!v.empty()) std::memcpy(a.data(), v.data(), v.size() * sizeof(T));
      return a;
    }
    const auto count = scalar<std::uint64_t>();
    if (expected_count != SIZE_MAX && count != expected_count)
      throw Error(context_ + ": array holds " + std::to_string(count) + " elements, expected " +
                  std::to_string(expected_count));
    if (count > (size_ - offset_) / sizeof(T)) throw Error(context_ + ": truncated (array runs past the end)");
    const std::byte* p = take(static_cast<std::size_t>(count) * sizeof(T));
    if (reinterpret_cast<std::uintptr_t>(p) % alignof(T) != 0) throw Error(context_ + ": misaligned array");
    return TableArray<T>::view(owner_, reinterpret_cast<const T*>(p), static_cast<std::size_t>(count));
  }
  /// Throws unless every byte was consumed (trailing garbage is corruption too).
  void finish() const {
    if (offset_ != size_) throw Error(context_ + ": " + std::to_string(size_ - offset_) + " unexpected trailing bytes");
  }
  const std::string& context() const { return context_; }

 private:
  const std::byte* take(std::size_t n) {
    const std::size_t padded = (n + 7) & ~std::size_t(7);
    if (padded > size_ - offset_) throw Error(context_ + ": truncated");
    const std::byte* p = data_ + offset_;
    offset_ += padded;
    return p;
  }
  const std::byte* data_;
  std::size_t size_;
  std::size_t offset_ = 0;
  std::string context_;
  std::shared_ptr<const void> owner_;
};

}  // namespace envkit
