#include <envkit/core/pixel_buffer.h>

#include <algorithm>
#include <utility>

namespace envkit {

PixelBuffer PixelBuffer::borrow(float* data, std::size_t n, std::shared_ptr<const void> lender) {
  PixelBuffer b;
  b.lender_ = std::move(lender);
  b.data_ = data;
  b.size_ = n;
  return b;
}

PixelBuffer& PixelBuffer::operator=(const PixelBuffer& other) {
  if (this != &other) {
    FloatBuffer copy(other.begin(), other.end());  // other may be a view of this buffer's own lender
    lender_.reset();
    owned_ = std::move(copy);
    attach();
  }
  return *this;
}

PixelBuffer::PixelBuffer(PixelBuffer&& other) noexcept
    : owned_(std::move(other.owned_)), lender_(std::move(other.lender_)), data_(other.data_), size_(other.size_) {
  other.owned_.clear();
  other.attach();
}

PixelBuffer& PixelBuffer::operator=(PixelBuffer&& other) noexcept {
  if (this != &other) {
    owned_ = std::move(other.owned_);
    lender_ = std::move(other.lender_);
    data_ = other.data_;
    size_ = other.size_;
    other.owned_.clear();
    other.lender_.reset();
    other.attach();
  }
  return *this;
}

PixelBuffer& PixelBuffer::operator=(FloatBuffer&& floats) {
  lender_.reset();
  owned_ = std::move(floats);
  attach();
  return *this;
}

FloatBuffer PixelBuffer::take() {
  FloatBuffer out = lender_ ? FloatBuffer(begin(), end()) : std::move(owned_);
  owned_.clear();
  lender_.reset();
  attach();
  return out;
}

void PixelBuffer::resize(std::size_t n, float value) {
  if (lender_) {
    FloatBuffer own(n, value);
    std::copy_n(data_, std::min(n, size_), own.data());
    lender_.reset();
    owned_ = std::move(own);
  } else {
    owned_.resize(n, value);
  }
  attach();
}

}  // namespace envkit
