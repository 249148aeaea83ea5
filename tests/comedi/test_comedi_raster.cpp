// The Comedi raster without a card: AO codes per scan (settle on the first pixel, the line,
// flyback ramp inside the field) and the AI samples assembled back into row-major pixels,
// whatever the chunking, with settle and flyback dropped and nothing written past the ROI.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "sempose/hal/comedi_raster.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace sempose::hal {
namespace {

std::vector<std::uint32_t> ramp(int n, std::uint32_t base, std::uint32_t step) {
  std::vector<std::uint32_t> v(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) v[static_cast<std::size_t>(i)] = base + step * static_cast<std::uint32_t>(i);
  return v;
}

TEST(ComediRaster, AoCodesFollowTheLineWithSettleAndFlyback) {
  const RasterShape shape{2, 3, 2};  // settle 2, flyback 3, oversample 2
  RasterWriter w(shape, ramp(20, 1000, 10), ramp(10, 5000, 100));
  const Roi roi{4, 2, 3, 2};  // columns 4..6, rows 2..3
  w.set_roi(roi);
  ASSERT_EQ(shape.scans(roi), 2 * (2 + 6 + 3));
  std::vector<std::uint16_t> ao(static_cast<std::size_t>(2 * shape.scans(roi)));
  EXPECT_EQ(w.fill(ao.data(), 1000), shape.scans(roi));  // stops at the end of the raster
  EXPECT_EQ(w.remaining(), 0);
  const std::uint16_t x4 = 1040, x6 = 1060, y2 = 5200, y3 = 5300;
  // line 0: settle on column 4, pixels 4,4,5,5,6,6, flyback ramp 6 -> 4 on the next row
  const std::vector<std::uint16_t> x0 = {x4, x4, 1040, 1040, 1050, 1050, 1060, 1060, 1055, 1050, 1045};
  for (std::size_t i = 0; i < x0.size(); ++i) {
    EXPECT_EQ(ao[2 * i], x0[i]) << "scan " << i;
    EXPECT_EQ(ao[2 * i + 1], i < 8 ? y2 : y3) << "scan " << i;
  }
  // line 1 (the last): same columns on row 3; its flyback stays on row 3
  for (std::size_t i = 0; i < x0.size(); ++i) {
    EXPECT_EQ(ao[2 * (11 + i)], x0[i]);
    EXPECT_EQ(ao[2 * (11 + i) + 1], y3);
  }
  EXPECT_LT(ao[2 * 8], x6);
}

TEST(ComediRaster, EveryCodeStaysInsideTheCalibratedField) {
  // A field calibrated from code 60000 (left) down to 2000 (right): inverted X, full field.
  std::vector<std::uint32_t> xs(64), ys(48);
  for (int i = 0; i < 64; ++i) xs[static_cast<std::size_t>(i)] = 60000 - 900u * static_cast<std::uint32_t>(i);
  for (int i = 0; i < 48; ++i) ys[static_cast<std::size_t>(i)] = 3000 + 1000u * static_cast<std::uint32_t>(i);
  const RasterShape shape{4, 16, 1};
  RasterWriter w(shape, xs, ys);
  for (const Roi& roi : {Roi{0, 0, 64, 48}, Roi{60, 40, 4, 8}, Roi{0, 47, 64, 1}}) {
    w.set_roi(roi);
    std::vector<std::uint32_t> ao(static_cast<std::size_t>(2 * shape.scans(roi)));
    w.fill(ao.data(), shape.scans(roi));
    for (std::size_t i = 0; i < ao.size(); i += 2) {
      ASSERT_LE(ao[i], xs.front());
      ASSERT_GE(ao[i], xs.back());
      ASSERT_GE(ao[i + 1], ys.front());
      ASSERT_LE(ao[i + 1], ys.back());
    }
  }
}

// AI samples that encode their own scan index, so the assembled pixels show exactly which
// samples went where.
TEST(ComediRaster, AssemblyIsRowMajorAndDropsSettleAndFlyback) {
  const RasterShape shape{3, 5, 2};
  const Roi roi{0, 0, 4, 3};
  const int channels = 2;
  const std::int64_t scans = shape.scans(roi);
  std::vector<std::uint16_t> ai(static_cast<std::size_t>(scans * channels));
  for (std::int64_t s = 0; s < scans; ++s) {
    ai[static_cast<std::size_t>(2 * s)] = static_cast<std::uint16_t>(s);      // detector 1
    ai[static_cast<std::size_t>(2 * s + 1)] = static_cast<std::uint16_t>(s);  // detector 2
  }
  // black 0, white 65535 → pixel = mean code at 16 bits.
  PixelAssembler a(shape, channels, 0.0, 65535.0, 65535);
  std::vector<Pixel> out(13, 0xBEEF);  // one pixel more than the ROI: must stay untouched
  a.set_roi(roi, out.data());
  EXPECT_EQ(a.consume(ai.data(), static_cast<std::int64_t>(ai.size()) + 100), static_cast<std::int64_t>(ai.size()));
  EXPECT_TRUE(a.complete());
  const int per_line = shape.scans_per_line(roi.w);  // 3 + 8 + 5 = 16
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      const int first = r * per_line + 3 + 2 * c;  // the pixel's two scans: first, first + 1
      // mean of codes first and first + 1 over both detectors = first + 0.5, rounded up
      EXPECT_EQ(out[static_cast<std::size_t>(r * 4 + c)], first + 1) << r << "," << c;
    }
  }
  EXPECT_EQ(out[12], 0xBEEF);
}

TEST(ComediRaster, ChunkedArrivalGivesTheSameFrameWithoutAllocating) {
  const RasterShape shape{4, 16, 1};
  const Roi roi{0, 0, 32, 24};
  const std::int64_t scans = shape.scans(roi);
  std::vector<std::uint16_t> ai(static_cast<std::size_t>(scans));
  std::uint32_t state = 12345;
  for (auto& v : ai) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<std::uint16_t>(state >> 16);
  }
  PixelAssembler whole(shape, 1, 0.0, 65535.0, 255);
  PixelAssembler chunked(shape, 1, 0.0, 65535.0, 255);
  std::vector<Pixel> a(32 * 24), b(32 * 24);
  whole.set_roi(roi, a.data());
  whole.consume(ai.data(), scans);
  chunked.set_roi(roi, b.data());
  const std::uint64_t before = rt::alloc::this_thread_allocations();
  rt::alloc::ScopedArm counting;
  std::int64_t at = 0;
  for (std::int64_t chunk = 1; at < scans; chunk = chunk * 3 % 97 + 1) {
    at += chunked.consume(ai.data() + at, std::min(chunk, scans - at));
  }
  EXPECT_EQ(rt::alloc::this_thread_allocations(), before);
  EXPECT_TRUE(chunked.complete());
  EXPECT_EQ(a, b);
}

TEST(ComediRaster, DetectorCalibrationMapsBlackAndWhite) {
  const RasterShape shape{0, 0, 1};
  const Roi roi{0, 0, 4, 1};
  // black 1000, white 3000 at 8 bits; a white below black inverts.
  const std::vector<std::uint16_t> ai = {500, 1000, 2000, 3500};
  PixelAssembler a(shape, 1, 1000.0, 3000.0, 255);
  std::vector<Pixel> out(4);
  a.set_roi(roi, out.data());
  a.consume(ai.data(), 4);
  EXPECT_EQ(out, (std::vector<Pixel>{0, 0, 128, 255}));
  PixelAssembler inv(shape, 1, 3000.0, 1000.0, 255);
  inv.set_roi(roi, out.data());
  inv.consume(ai.data(), 4);
  EXPECT_EQ(out, (std::vector<Pixel>{255, 255, 128, 0}));
}

}  // namespace
}  // namespace sempose::hal
