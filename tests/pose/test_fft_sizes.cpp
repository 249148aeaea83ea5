// Property: every FFT size the config allows either works — an FFTW plan exists, executing
// it makes no heap call, and it gives exact ZNCC scores — or setup refuses it with a message.
// Some sizes have no allocation-free FFTW plan (FFTW_NO_BUFFERING returns NULL, e.g. the 75²
// transform behind a 150 px ROI); the correlator then pads to the next 2,3,5-smooth size.
// Runs in the sanitizer build too, where the heap counter sees FFTW's own mallocs (the
// sanitizer allocator's hooks), so a plan that mallocs inside fftwf_execute cannot pass.
#include <fftw3.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <utility>
#include <vector>

#include "sempose/config/tracker_config.hpp"
#include "sempose/config/scan_config.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/pattern_support.hpp"
#include "sempose/rt/alloc_counter.hpp"

namespace sempose::pose {
namespace {

// A w×h region holding a pattern at (ux, uy) on a textured background; the correlator must
// score exactly 1 there and below 1 elsewhere (checks the padded transform's geometry).
void check_size(int want_w, int want_h, int& padded) {
  const int p = std::min({16, want_w, want_h});
  PatternMask mask(p, false);
  FftCorrelator z(want_w, want_h, mask);
  ASSERT_GE(z.fft_w(), want_w);
  ASSERT_GE(z.fft_h(), want_h);
  if (z.fft_w() != want_w || z.fft_h() != want_h) ++padded;
  EXPECT_FALSE(z.execute_allocates()) << want_w << "x" << want_h << ": no allocation-free plan";
  std::vector<std::int32_t> img(static_cast<std::size_t>(want_w) * want_h);
  for (std::size_t i = 0; i < img.size(); ++i) img[i] = static_cast<std::int32_t>((i * 2654435761u >> 7) % 200);
  const int ux = (want_w - p) / 3, uy = (want_h - p) / 2;
  std::vector<float> pat(static_cast<std::size_t>(p) * p);
  for (int y = 0; y < p; ++y)
    for (int x = 0; x < p; ++x) pat[static_cast<std::size_t>(y * p + x)] = static_cast<float>(img[static_cast<std::size_t>((uy + y) * want_w + ux + x)]);
  ASSERT_TRUE(normalize_pattern(pat.data(), mask));
  std::vector<FftCorrelator::Complex> spec(z.spectrum_len());
  z.make_spectrum(pat.data(), spec.data());
  std::vector<float> out(static_cast<std::size_t>(want_w) * want_h);
  {
    rt::alloc::ScopedArm arm;
    const std::uint64_t before = rt::alloc::this_thread_allocations();
    ASSERT_TRUE(z.load(img.data(), want_w, want_h, want_w));
    z.correlate(spec.data(), out.data());
    EXPECT_EQ(rt::alloc::this_thread_allocations(), before) << want_w << "x" << want_h << ": heap call in the loop";
  }
  const float at = out[static_cast<std::size_t>(uy * z.valid_w() + ux)];
  EXPECT_NEAR(at, 1.0f, 2e-3f) << want_w << "x" << want_h << " (fft " << z.fft_w() << "x" << z.fft_h() << ")";
}

// FFTW_MEASURE over ~150 sizes takes minutes on a shared 2-core machine; a planner time limit
// keeps each plan under 20 ms. The plan FFTW then picks may differ from the product's, which
// is the point: the fallback chain must give an allocation-free plan whatever is picked.
class PlannerTimeLimit : public ::testing::Environment {
 public:
  void SetUp() override { fftwf_set_timelimit(0.02); }
};
const auto* const kTimeLimit = ::testing::AddGlobalTestEnvironment(new PlannerTimeLimit);

std::set<int> smooth_sizes(int lo, int hi) {
  std::set<int> s;
  for (int n = lo; n <= hi; ++n) s.insert(good_fft_size(n));
  return s;
}

TEST(FftSizes, EveryRoiTransformWorks) {
  // tracker.roi_size_px 8..1024: N = good(R), the binned transform good(N / 2).
  std::set<int> half;
  for (int r = 8; r <= 1024; ++r) half.insert(good_fft_size(good_fft_size(r) / 2));
  int padded = 0;
  for (int n : half) {
    if (n < 4) continue;
    check_size(n, n, padded);
  }
  std::printf("%zu ROI transform sizes (4..512 px), %d padded to a larger allocation-free size\n", half.size(), padded);
}

TEST(FftSizes, EveryStartSearchTransformWorks) {
  // The coarse transform is good(field / search_downsample) per side (capped at 2048 by the
  // tracker's size check): every smooth side length, each with a 4:3 and a square partner,
  // and the widths reported to crash (1000, 1040, 1800 at the default downsample 8).
  int padded = 0, count = 0;
  for (int n : smooth_sizes(4, 1024)) {
    check_size(n, good_fft_size(std::max(4, n * 3 / 4)), padded);
    ++count;
  }
  for (int w : {1000, 1040, 1800, 16384}) {
    check_size(good_fft_size(w / 8), good_fft_size(768 / 8), padded);
    ++count;
  }
  std::printf("%d start-search transform shapes, %d padded\n", count, padded);
}

TEST(FftSizes, TrackerSetupAtSizesThatOnceCrashed) {
  // roi_size_px 150 (the 75² transform) and field widths 1000, 1040, 1800 crashed at setup:
  // a NULL FFTW plan was executed.
  struct Case {
    int roi, pattern, field_w, field_h;
  };
  for (const Case& c : {Case{150, 64, 640, 480}, Case{160, 128, 1000, 700}, Case{192, 128, 1040, 768},
                        Case{96, 64, 1800, 600}, Case{1024, 512, 1024, 1024}, Case{8, 8, 16, 16}}) {
    config::TrackerConfig tc;
    tc.roi_size_px = c.roi;
    tc.pattern_size_px = c.pattern;
    tc.search_downsample = std::max(1, std::min(8, c.pattern / 4));
    config::ScanLimits limits;
    limits.field_w = c.field_w;
    limits.field_h = c.field_h;
    limits.max_roi_w = std::min(c.field_w, std::max(256, c.roi));
    limits.max_roi_h = std::min(c.field_h, std::max(256, c.roi));
    std::vector<PatternSet> sets(1);
    sets[0].image.width = sets[0].image.height = c.pattern;
    sets[0].image.pixels.resize(static_cast<std::size_t>(c.pattern) * c.pattern);
    for (std::size_t i = 0; i < sets[0].image.pixels.size(); ++i)
      sets[0].image.pixels[i] = static_cast<std::uint16_t>((i * 2654435761u >> 9) % 256);
    rt::Status st;
    auto t = Tracker::create(tc, std::move(sets), limits, st);
    if (!t) {
      // Refused with a reason is fine (an 8 px pattern keeps 1-2 px inside its mask); a crash is not.
      EXPECT_FALSE(st.message.empty());
      std::printf("roi %4d pattern %3d field %4dx%-4d: refused: %s\n", c.roi, c.pattern, c.field_w, c.field_h,
                  st.message.c_str());
      continue;
    }
    EXPECT_EQ(st.message.find("may call malloc"), std::string::npos) << st.message;
    std::printf("roi %4d pattern %3d field %4dx%-4d: ok, noise floors roi %.3f field %.3f\n", c.roi, c.pattern,
                c.field_w, c.field_h, t->noise_floor_roi(0), t->noise_floor_field(0));
  }
}

}  // namespace
}  // namespace sempose::pose
