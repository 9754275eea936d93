#pragma once
/// @file table_blob.h
/// Flat binary images of in-memory tables, the payload of table-file sections (env_tables.h).
///
/// A blob is a sequence of fields, each 8-byte aligned: scalars as their raw bytes, arrays as a 64-bit element
/// count followed by the raw elements. Byte order and float format are the writer's (little-endian IEEE 754 on
/// every platform envkit builds on; the table file header records it). Reading copies each array with one
/// memcpy, so loading costs a pass over memory, never per-element parsing. Every read is bounds-checked: a blob
/// that ends early or claims more elements than it holds is an Error naming the context, never an overread.
#include <envkit/error.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace envkit {

class BlobWriter {
 public:
  template <class T>
  void scalar(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    append(&value, sizeof(T));
  }
  template <class T>
  void array(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>);
    scalar<std::uint64_t>(values.size());
    append(values.data(), values.size() * sizeof(T));
  }
  const std::vector<std::byte>& bytes() const { return bytes_; }
  std::vector<std::byte> release() { return std::move(bytes_); }

 private:
  void append(const void* data, std::size_t n) {
    const std::size_t at = bytes_.size();
    bytes_.resize(at + ((n + 7) & ~std::size_t(7)), std::byte{0});
    if (n) std::memcpy(bytes_.data() + at, data, n);
  }
  std::vector<std::byte> bytes_;
};

class BlobReader {
 public:
  /// context names the blob in errors, e.g. "table.envtbl: section cdf".
  BlobReader(const std::byte* data, std::size_t size, std::string context)
      : data_(data), size_(size), context_(std::move(context)) {}

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
};

}  // namespace envkit
