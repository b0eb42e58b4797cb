// A float image: width x height pixels of `channels` interleaved floats, row-major.
// Views are non-owning (pointer, size, row stride) and cost nothing to pass around.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace dnb {

// Rec. 709 luminance of a linear RGB pixel (three floats).
inline float luminance(const float* rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

template <typename T>
struct BasicImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  int channels = 0;
  std::size_t row_stride = 0;  // floats between the starts of consecutive rows

  BasicImageView() = default;
  BasicImageView(T* d, int w, int h, int c, std::size_t stride)
      : data(d), width(w), height(h), channels(c), row_stride(stride) {}
  // A mutable view converts to a read-only one.
  template <typename U, typename = std::enable_if_t<std::is_same_v<T, const U>>>
  BasicImageView(const BasicImageView<U>& o)
      : data(o.data), width(o.width), height(o.height), channels(o.channels), row_stride(o.row_stride) {}

  T* pixel(int x, int y) const { return data + std::size_t(y) * row_stride + std::size_t(x) * channels; }
  T& at(int x, int y, int c) const { return pixel(x, y)[c]; }
  T* row(int y) const { return data + std::size_t(y) * row_stride; }
  bool empty() const { return width == 0 || height == 0; }
  // A rectangular window of this view (no copy). The caller keeps it inside the view.
  BasicImageView crop(int x0, int y0, int w, int h) const {
    return BasicImageView{pixel(x0, y0), w, h, channels, row_stride};
  }
};

using ImageView = BasicImageView<float>;
using ConstImageView = BasicImageView<const float>;

// std::allocator, except that a value-less construct() leaves a float as it is (no zero): for
// images whose every value is written before it is read (Image's NoFill constructor).
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  using std::allocator<T>::allocator;
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

class Image {
 public:
  // Largest accepted side and pixel count: far above any render, far below what would
  // overflow an index or exhaust memory silently. Larger sizes are refused with InputError.
  static constexpr int kMaxSide = 1 << 15;
  static constexpr std::int64_t kMaxPixels = std::int64_t(1) << 28;

  Image() = default;
  Image(int width, int height, int channels, float fill = 0.0f);
  // An image whose values are left unset, for a writer that sets every one before anything reads
  // them (the tracer's frame layers: zero-filling a 1024x768 frame's 330 MB only for the main
  // pass to overwrite them).
  struct NoFill {};
  Image(int width, int height, int channels, NoFill);

  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  std::size_t pixel_count() const { return std::size_t(width_) * height_; }
  std::size_t size() const { return data_.size(); }
  bool empty() const { return data_.empty(); }

  float* data() { return data_.data(); }
  const float* data() const { return data_.data(); }
  float* pixel(int x, int y) { return data_.data() + (std::size_t(y) * width_ + x) * channels_; }
  const float* pixel(int x, int y) const {
    return data_.data() + (std::size_t(y) * width_ + x) * channels_;
  }
  float& at(int x, int y, int c) { return pixel(x, y)[c]; }
  float at(int x, int y, int c) const { return pixel(x, y)[c]; }

  ImageView view() { return {data_.data(), width_, height_, channels_, std::size_t(width_) * channels_}; }
  ConstImageView view() const {
    return {data_.data(), width_, height_, channels_, std::size_t(width_) * channels_};
  }
  ConstImageView cview() const { return view(); }

  bool same_shape(const Image& o) const {
    return width_ == o.width_ && height_ == o.height_ && channels_ == o.channels_;
  }
  bool operator==(const Image& o) const { return same_shape(o) && data_ == o.data_; }

  // Throws InputError when width x height x channels is not a sane image size.
  static void check_size(int width, int height, int channels, const char* what);

 private:
  int width_ = 0;
  int height_ = 0;
  int channels_ = 0;
  std::vector<float, DefaultInitAllocator<float>> data_;
};

// Copies a view into a new owning image.
Image to_image(ConstImageView v);

// Counts samples that are NaN or infinite.
std::size_t count_non_finite(ConstImageView v);

// How far a is from b: sqrt(sum (a - b)^2 / sum b^2) over n values (sqrt(sum (a - b)^2) where b
// is all zero), in double. The OpenCL paths' agreement measure (tests, bench/device/).
double relative_rms(const float* a, const float* b, std::size_t n);
inline double relative_rms(const Image& a, const Image& b) { return relative_rms(a.data(), b.data(), b.size()); }

}  // namespace dnb
