#include "sempose/hal/comedi_raster.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace sempose::hal {

RasterWriter::RasterWriter(RasterShape shape, std::vector<std::uint32_t> x_codes, std::vector<std::uint32_t> y_codes)
    : shape_(shape), x_codes_(std::move(x_codes)), y_codes_(std::move(y_codes)) {}

void RasterWriter::set_roi(const Roi& roi) noexcept {
  roi_ = roi;
  per_line_ = shape_.scans_per_line(roi.w);
  total_ = shape_.scans(roi);
  done_ = 0;
  line_ = pos_ = 0;
}

std::uint32_t RasterWriter::x_at(std::int32_t p) const noexcept {
  const std::uint32_t first = x_codes_[static_cast<std::size_t>(roi_.x)];
  if (p < shape_.settle) return first;
  const std::int32_t in_line = p - shape_.settle;
  if (in_line < roi_.w * shape_.oversample) {
    return x_codes_[static_cast<std::size_t>(roi_.x + in_line / shape_.oversample)];
  }
  // Flyback: a linear ramp from the last pixel back to the first, ending one step short of it
  // (the settle scans of the next line sit on it). Between two field codes: inside the field.
  const std::int64_t last = x_codes_[static_cast<std::size_t>(roi_.x + roi_.w - 1)];
  const std::int64_t f = in_line - roi_.w * shape_.oversample + 1;
  const std::int64_t n = shape_.flyback + 1;
  return static_cast<std::uint32_t>(last + (static_cast<std::int64_t>(first) - last) * f / n);
}

template <typename Sample>
std::int64_t RasterWriter::fill(Sample* out, std::int64_t scans) noexcept {
  const std::int64_t n = std::min(scans, total_ - done_);
  const std::int32_t pixels_end = shape_.settle + roi_.w * shape_.oversample;
  for (std::int64_t i = 0; i < n; ++i) {
    // During flyback the beam is already on the next line (the last line returns to its own).
    const std::int32_t row = pos_ >= pixels_end && line_ + 1 < roi_.h ? line_ + 1 : line_;
    out[2 * i] = static_cast<Sample>(x_at(pos_));
    out[2 * i + 1] = static_cast<Sample>(y_codes_[static_cast<std::size_t>(roi_.y + row)]);
    if (++pos_ == per_line_) {
      pos_ = 0;
      ++line_;
    }
  }
  done_ += n;
  return n;
}

template std::int64_t RasterWriter::fill<std::uint16_t>(std::uint16_t*, std::int64_t) noexcept;
template std::int64_t RasterWriter::fill<std::uint32_t>(std::uint32_t*, std::int64_t) noexcept;

PixelAssembler::PixelAssembler(RasterShape shape, std::int32_t channels, double black_code, double white_code,
                               std::uint16_t max_value) noexcept
    : shape_(shape), channels_(channels), black_(black_code), max_value_(max_value) {
  const double per_pixel = static_cast<double>(shape.oversample) * channels;
  scale_ = static_cast<float>(max_value / ((white_code - black_code) * per_pixel));
}

void PixelAssembler::set_roi(const Roi& roi, Pixel* out) noexcept {
  roi_ = roi;
  out_ = out;
  per_line_ = shape_.scans_per_line(roi.w);
  pixel_begin_ = shape_.settle;
  pixel_end_ = shape_.settle + roi.w * shape_.oversample;
  total_samples_ = shape_.scans(roi) * channels_;
  done_samples_ = 0;
  pos_ = chan_ = in_pixel_ = 0;
  written_ = 0;
  acc_ = 0;
}

template <typename Sample>
std::int64_t PixelAssembler::consume(const Sample* in, std::int64_t samples) noexcept {
  const std::int64_t n = std::min(samples, total_samples_ - done_samples_);
  const double offset = black_ * shape_.oversample * channels_;
  const float top = static_cast<float>(max_value_);
  for (std::int64_t i = 0; i < n; ++i) {
    const bool on_pixel = pos_ >= pixel_begin_ && pos_ < pixel_end_;
    if (on_pixel) acc_ += in[i];
    if (++chan_ < channels_) continue;
    chan_ = 0;
    if (on_pixel && ++in_pixel_ == shape_.oversample) {
      const float v = static_cast<float>(static_cast<double>(acc_) - offset) * scale_;
      out_[written_++] = static_cast<Pixel>(std::lround(std::clamp(v, 0.0f, top)));
      acc_ = 0;
      in_pixel_ = 0;
    }
    if (++pos_ == per_line_) pos_ = 0;
  }
  done_samples_ += n;
  return n;
}

template std::int64_t PixelAssembler::consume<std::uint16_t>(const std::uint16_t*, std::int64_t) noexcept;
template std::int64_t PixelAssembler::consume<std::uint32_t>(const std::uint32_t*, std::int64_t) noexcept;

}  // namespace sempose::hal
