// The ROI raster of an external scan, as the Comedi scan source streams it: per line
// `settle` AI/AO scans with the beam on the line's first pixel (dropped: the deflection
// amplifier settles), `w × oversample` scans on the pixels, then `flyback` scans while the beam
// is ramped back to the next line's start (dropped). One AO update (X, Y) per AI scan.
//
// RasterWriter makes the AO codes, PixelAssembler turns the AI samples back into row-major
// pixels. Both keep their place between calls, so the caller may hand them any chunk of
// samples (ring-buffer wrap, partial arrivals). Setup (the code tables) allocates; set_roi,
// fill and consume are noexcept and allocation-free.
#pragma once

#include <cstdint>
#include <vector>

#include "sempose/hal/frame.hpp"

namespace sempose::hal {

struct RasterShape {
  std::int32_t settle = 0;      // scans at each line start, dropped
  std::int32_t flyback = 0;     // scans at each line end, dropped
  std::int32_t oversample = 1;  // scans per pixel
  std::int32_t scans_per_line(std::int32_t w) const noexcept { return settle + w * oversample + flyback; }
  std::int64_t scans(const Roi& r) const noexcept { return static_cast<std::int64_t>(r.h) * scans_per_line(r.w); }
};

// Maps field pixel columns/rows to AO codes (the field calibration); every code it can emit
// lies between the codes of the field's first and last pixel.
class RasterWriter {
 public:
  // x_codes[c]: AO code of column c (field_w entries); y_codes[r]: of row r (field_h).
  RasterWriter(RasterShape shape, std::vector<std::uint32_t> x_codes, std::vector<std::uint32_t> y_codes);

  void set_roi(const Roi& roi) noexcept;
  // Writes the next `scans` AO scans as interleaved (x, y) samples; returns how many it wrote
  // (fewer at the end of the raster).
  template <typename Sample>
  std::int64_t fill(Sample* out, std::int64_t scans) noexcept;
  std::int64_t remaining() const noexcept { return total_ - done_; }

 private:
  std::uint32_t x_at(std::int32_t p) const noexcept;
  RasterShape shape_;
  std::vector<std::uint32_t> x_codes_, y_codes_;
  Roi roi_{};
  std::int32_t per_line_ = 0;
  std::int64_t total_ = 0, done_ = 0;
  std::int32_t line_ = 0, pos_ = 0;
};

// Averages the samples of each pixel (oversample × channels) and maps them to 8/16-bit pixels.
class PixelAssembler {
 public:
  // black/white: AI codes shown as 0 and max_value (white < black inverts).
  PixelAssembler(RasterShape shape, std::int32_t channels, double black_code, double white_code,
                 std::uint16_t max_value) noexcept;

  void set_roi(const Roi& roi, Pixel* out) noexcept;
  // Consumes `samples` AI samples (channels interleaved); returns how many it took (it stops
  // at the end of the raster, so extra samples are never written past the ROI).
  template <typename Sample>
  std::int64_t consume(const Sample* in, std::int64_t samples) noexcept;
  std::int64_t samples_total() const noexcept { return total_samples_; }
  std::int64_t samples_done() const noexcept { return done_samples_; }
  bool complete() const noexcept { return done_samples_ == total_samples_; }

 private:
  RasterShape shape_;
  std::int32_t channels_;
  double black_;
  float scale_;  // pixel per summed code above black × samples
  std::uint16_t max_value_;
  Roi roi_{};
  Pixel* out_ = nullptr;
  std::int64_t total_samples_ = 0, done_samples_ = 0;
  std::int32_t per_line_ = 0, pixel_begin_ = 0, pixel_end_ = 0;
  std::int32_t pos_ = 0, chan_ = 0, in_pixel_ = 0;
  std::int64_t written_ = 0;
  std::uint64_t acc_ = 0;
};

}  // namespace sempose::hal
