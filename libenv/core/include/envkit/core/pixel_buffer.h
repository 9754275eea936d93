#pragma once
/// @file pixel_buffer.h
/// The float storage of an Image: its own huge-page-backed block (FloatBuffer), or floats it borrows from a caller
/// that keeps them alive (a numpy array handed to the Python module, which then needs no copy).
///
/// Borrowed floats are a view: writes through data() reach the lender's memory, and the lender's writes show here.
/// A copy of a buffer always owns its floats (copying never shares a lender), and an operation that changes the size
/// (resize, assign) first moves a borrowed buffer into storage of its own. Moving transfers ownership or the loan.
#include <envkit/core/huge_page_allocator.h>

#include <algorithm>
#include <cstddef>
#include <initializer_list>
#include <memory>

namespace envkit {

class PixelBuffer {
 public:
  PixelBuffer() = default;
  /// n floats, each `value`.
  explicit PixelBuffer(std::size_t n, float value = 0.0f) : owned_(n, value) { attach(); }
  PixelBuffer(FloatBuffer&& floats) : owned_(std::move(floats)) { attach(); }  // NOLINT: implicit by design
  PixelBuffer(std::initializer_list<float> values) : owned_(values) { attach(); }
  /// A view of n floats at `data`, which `lender` keeps alive for as long as this buffer (or one moved from it)
  /// uses them.
  static PixelBuffer borrow(float* data, std::size_t n, std::shared_ptr<const void> lender);

  PixelBuffer(const PixelBuffer& other) : owned_(other.begin(), other.end()) { attach(); }
  PixelBuffer& operator=(const PixelBuffer& other);
  PixelBuffer(PixelBuffer&& other) noexcept;
  PixelBuffer& operator=(PixelBuffer&& other) noexcept;
  PixelBuffer& operator=(FloatBuffer&& floats);
  PixelBuffer& operator=(std::initializer_list<float> values) { return *this = FloatBuffer(values); }

  float* data() { return data_; }
  const float* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  float* begin() { return data_; }
  float* end() { return data_ + size_; }
  const float* begin() const { return data_; }
  const float* end() const { return data_ + size_; }
  float& operator[](std::size_t i) { return data_[i]; }
  const float& operator[](std::size_t i) const { return data_[i]; }
  /// Same size and equal floats (as std::vector's ==).
  friend bool operator==(const PixelBuffer& a, const PixelBuffer& b) {
    return a.size_ == b.size_ && std::equal(a.begin(), a.end(), b.begin());
  }

  /// True while the floats are a caller's (borrow()).
  bool borrowed() const { return lender_ != nullptr; }

  /// The floats as a FloatBuffer: moved out when owned, copied when borrowed; this buffer is left empty.
  FloatBuffer take();

  void resize(std::size_t n, float value = 0.0f);
  template <class It>
  void assign(It first, It last) {
    lender_.reset();
    owned_.assign(first, last);
    attach();
  }

 private:
  void attach() {
    data_ = owned_.data();
    size_ = owned_.size();
  }

  FloatBuffer owned_;
  std::shared_ptr<const void> lender_;  // set while borrowed: data_ points into the lender's memory
  float* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace envkit
