// PixelBuffer: an image's own floats or a caller's (pixel_buffer.h). Borrowed floats are a view kept alive by the
// lender; copies own their floats; size changes detach from the lender.
#include <envkit/core/image.h>
#include <gtest/gtest.h>

#include <memory>
#include <vector>

using envkit::Image;
using envkit::PixelBuffer;

namespace {

/// A lender whose floats live as long as the returned shared_ptr (and its copies).
std::shared_ptr<std::vector<float>> lender(std::size_t n) {
  auto v = std::make_shared<std::vector<float>>(n);
  for (std::size_t i = 0; i < n; ++i) (*v)[i] = float(i);
  return v;
}

}  // namespace

TEST(PixelBuffer, BorrowedFloatsAreAViewKeptAliveByTheBuffer) {
  std::weak_ptr<std::vector<float>> watch;
  float* floats = nullptr;
  PixelBuffer b;
  {
    auto v = lender(12);
    watch = v;
    floats = v->data();
    b = PixelBuffer::borrow(v->data(), v->size(), v);
  }
  ASSERT_FALSE(watch.expired()) << "the buffer keeps its lender alive";
  EXPECT_TRUE(b.borrowed());
  EXPECT_EQ(b.data(), floats);
  EXPECT_EQ(b.size(), 12u);
  b[3] = 42.0f;  // a view: writes reach the lender's memory
  EXPECT_EQ(floats[3], 42.0f);
  PixelBuffer moved = std::move(b);  // the loan moves with the floats
  EXPECT_TRUE(moved.borrowed());
  EXPECT_EQ(moved.data(), floats);
  EXPECT_TRUE(b.empty());
  EXPECT_FALSE(watch.expired());
  moved = PixelBuffer(4, 1.0f);
  EXPECT_TRUE(watch.expired()) << "replacing the floats releases the lender";
}

TEST(PixelBuffer, CopiesOwnTheirFloatsAndSizeChangesDetach) {
  auto v = lender(6);
  Image image;
  image.width = 2;
  image.height = 1;
  image.channels = 3;
  image.pixels = PixelBuffer::borrow(v->data(), v->size(), v);
  const Image copy = image;  // never shares the lender
  EXPECT_FALSE(copy.pixels.borrowed());
  EXPECT_NE(copy.pixels.data(), v->data());
  EXPECT_EQ(copy.pixels, image.pixels);
  PixelBuffer assigned(2);
  assigned = image.pixels;
  EXPECT_FALSE(assigned.borrowed());
  EXPECT_EQ(assigned, image.pixels);

  const long uses = v.use_count();
  image.pixels.resize(8, -1.0f);  // copies the borrowed prefix into storage of its own
  EXPECT_FALSE(image.pixels.borrowed());
  EXPECT_EQ(v.use_count(), uses - 1);
  ASSERT_EQ(image.pixels.size(), 8u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(image.pixels[i], float(i));
  EXPECT_EQ(image.pixels[7], -1.0f);
  image.pixels[0] = 9.0f;
  EXPECT_EQ((*v)[0], 0.0f) << "a detached buffer no longer writes to the lender";

  PixelBuffer b = PixelBuffer::borrow(v->data(), v->size(), v);
  const envkit::FloatBuffer taken = b.take();  // a borrowed buffer gives a copy
  EXPECT_NE(taken.data(), v->data());
  EXPECT_EQ(taken.size(), 6u);
  EXPECT_TRUE(b.empty());
  PixelBuffer owned(envkit::FloatBuffer{1.0f, 2.0f});
  const float* at = owned.data();
  const envkit::FloatBuffer moved_out = owned.take();  // an owned buffer gives its storage
  EXPECT_EQ(moved_out.data(), at);
}
