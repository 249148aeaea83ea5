// The correlator against a brute-force masked ZNCC, flat and saturated inputs, the mask and
// the rotation convention.
// GCC 12 -O3 reports a false null dereference inside gtest.h's comparison helpers.
#pragma GCC diagnostic ignored "-Wnull-dereference"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "sempose/pose/bicubic_rotate.hpp"
#include "sempose/pose/exact_scorer.hpp"
#include "sempose/pose/fft_correlator.hpp"
#include "sempose/pose/pattern_bank.hpp"

using namespace sempose::pose;

namespace {

// Smooth random texture (sum of blurred noise) so correlations have structure.
std::vector<std::uint16_t> texture(int w, int h, unsigned seed, int lo = 20, int hi = 230) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> v(static_cast<std::size_t>(w) * h);
  for (auto& x : v) x = u(rng);
  std::vector<double> b(v.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0;
      int n = 0;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          const int xx = x + i, yy = y + j;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          s += v[yy * w + xx];
          ++n;
        }
      b[y * w + x] = s / n;
    }
  std::vector<std::uint16_t> out(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) out[i] = static_cast<std::uint16_t>(lo + (hi - lo) * b[i]);
  return out;
}

// The bank settings of the shape-mask tests: one prefilter pass, 10° steps, coarse 30° at ×8.
PatternBankSpec bank_spec(const PatternImage& pattern, const PatternImage& shape) {
  PatternBankSpec spec;
  spec.pattern = pattern;
  spec.shape = shape;
  spec.prefilter_passes = 1;
  spec.angle_step_deg = 10.0;
  spec.coarse_step_deg = 30.0;
  spec.coarse_factor = 8;
  return spec;
}

double brute_zncc(const std::vector<std::uint16_t>& img, int w, const std::vector<float>& raw_pattern, int n,
                  const PatternMask& mask, int ux, int uy) {
  double st = 0, sf = 0;
  const double count = static_cast<double>(mask.count());
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (mask.inside(x, y)) {
        st += raw_pattern[y * n + x];
        sf += img[(uy + y) * w + ux + x];
      }
  const double mt = st / count, mf = sf / count;
  double num = 0, dt = 0, df = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (mask.inside(x, y)) {
        const double a = raw_pattern[y * n + x] - mt, b = img[(uy + y) * w + ux + x] - mf;
        num += a * b;
        dt += a * a;
        df += b * b;
      }
  if (dt <= 0 || df <= 0) return 0;
  return num / std::sqrt(dt * df);
}

}  // namespace

TEST(FftSize, SmallPrimeFactors) {
  EXPECT_EQ(good_fft_size(192), 192);
  EXPECT_EQ(good_fft_size(161), 162);
  EXPECT_EQ(good_fft_size(97), 100);
  EXPECT_EQ(good_fft_size(1), 1);
}

TEST(PatternMask, InscribedAndSymmetric) {
  const PatternMask m(32, true);
  const double c = 15.5;
  int count = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      if (!m.inside(x, y)) continue;
      ++count;
      // Every pixel's far corner stays inside the circle of radius 16.
      EXPECT_LE(std::hypot(std::fabs(x - c) + 0.5, std::fabs(y - c) + 0.5), 16.0 + 1e-9);
      EXPECT_TRUE(m.inside(31 - x, y));
      EXPECT_TRUE(m.inside(x, 31 - y));
    }
  EXPECT_EQ(count, m.count());
  EXPECT_GT(count, 0.7 * M_PI * 16 * 16);  // the staircase keeps most of the disc
  EXPECT_FALSE(m.inside(0, 0));
  const PatternMask full(8, false);
  EXPECT_EQ(full.count(), 64);
}

class ZnccBrute : public ::testing::TestWithParam<bool> {};

TEST_P(ZnccBrute, MatchesBruteForceEverywhere) {
  const bool circular = GetParam();
  const int n = 16, w = 40, h = 34;
  const PatternMask mask(n, circular);
  const auto img = texture(w, h, 7);
  // The pattern: a crop of the image at (11, 9) plus a different texture, so scores vary.
  const auto other = texture(n, n, 99);
  std::vector<float> raw(static_cast<std::size_t>(n) * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) raw[y * n + x] = 0.8f * img[(9 + y) * w + 11 + x] + 0.2f * other[y * n + x];
  std::vector<float> pat = raw;
  ASSERT_TRUE(normalize_pattern(pat.data(), mask));
  FftCorrelator corr(good_fft_size(w), good_fft_size(h), mask);
  std::vector<FftCorrelator::Complex> spec(corr.spectrum_len());
  corr.make_spectrum(pat.data(), spec.data());
  ASSERT_TRUE(corr.load(img.data(), w, h, w));
  ASSERT_EQ(corr.valid_w(), w - n + 1);
  ASSERT_EQ(corr.valid_h(), h - n + 1);
  std::vector<float> map(static_cast<std::size_t>(corr.valid_w()) * corr.valid_h());
  corr.correlate(spec.data(), map.data());
  double max_err = 0;
  int best = 0;
  for (int uy = 0; uy < corr.valid_h(); ++uy)
    for (int ux = 0; ux < corr.valid_w(); ++ux) {
      const double ref = brute_zncc(img, w, raw, n, mask, ux, uy);
      const float got = map[uy * corr.valid_w() + ux];
      max_err = std::max(max_err, std::fabs(ref - got));
      EXPECT_GE(got, -1.0f);
      EXPECT_LE(got, 1.0f);
      if (got > map[best]) best = uy * corr.valid_w() + ux;
    }
  EXPECT_LT(max_err, 1e-4);
  EXPECT_EQ(best % corr.valid_w(), 11);
  EXPECT_EQ(best / corr.valid_w(), 9);
}
INSTANTIATE_TEST_SUITE_P(Masks, ZnccBrute, ::testing::Values(true, false));

TEST(Zncc, SmallerRegionAndStrideAgree) {
  const int n = 12, W = 60, H = 50;
  const PatternMask mask(n, true);
  const auto img = texture(W, H, 3);
  std::vector<float> raw(n * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) raw[y * n + x] = img[(20 + y) * W + 30 + x];
  auto pat = raw;
  ASSERT_TRUE(normalize_pattern(pat.data(), mask));
  FftCorrelator corr(48, 48, mask);
  std::vector<FftCorrelator::Complex> spec(corr.spectrum_len());
  corr.make_spectrum(pat.data(), spec.data());
  // A 30x25 sub-window starting at (15, 12) of the big image, read through the stride.
  ASSERT_TRUE(corr.load(img.data() + 12 * W + 15, 30, 25, W));
  std::vector<float> map(corr.valid_w() * corr.valid_h());
  corr.correlate(spec.data(), map.data());
  for (int uy = 0; uy < corr.valid_h(); ++uy)
    for (int ux = 0; ux < corr.valid_w(); ++ux)
      EXPECT_NEAR(map[uy * corr.valid_w() + ux], brute_zncc(img, W, raw, n, mask, 15 + ux, 12 + uy), 1e-4);
  EXPECT_NEAR(map[8 * corr.valid_w() + 15], 1.0, 1e-4);
}

TEST(Zncc, FlatAndSaturatedScoreZeroNotNan) {
  const int n = 16;
  const PatternMask mask(n, true);
  const auto t = texture(n, n, 5);
  std::vector<float> pat(t.begin(), t.end());
  ASSERT_TRUE(normalize_pattern(pat.data(), mask));
  FftCorrelator corr(48, 48, mask);
  std::vector<FftCorrelator::Complex> spec(corr.spectrum_len());
  corr.make_spectrum(pat.data(), spec.data());
  for (std::uint16_t level : {std::uint16_t{0}, std::uint16_t{255}, std::uint16_t{65535}, std::uint16_t{77}}) {
    std::vector<std::uint16_t> img(48 * 48, level);
    EXPECT_FALSE(corr.load(img.data(), 48, 48, 48));
    std::vector<float> map(corr.valid_w() * corr.valid_h(), 5.0f);
    corr.correlate(spec.data(), map.data());
    for (float v : map) EXPECT_EQ(v, 0.0f);
  }
  // Half flat, half textured: the flat windows score 0, the rest stay finite and bounded.
  auto img = texture(48, 48, 11);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 24; ++x) img[y * 48 + x] = 255;
  EXPECT_TRUE(corr.load(img.data(), 48, 48, 48));
  std::vector<float> map(corr.valid_w() * corr.valid_h());
  corr.correlate(spec.data(), map.data());
  EXPECT_EQ(map[0], 0.0f);
  for (float v : map) {
    EXPECT_TRUE(std::isfinite(v));
    EXPECT_LE(std::fabs(v), 1.0f);
  }
  const PatternMask m2(8, true);
  std::vector<float> flat(64, 3.0f);
  EXPECT_FALSE(normalize_pattern(flat.data(), m2));
}

// A 16² pattern's bank without prefilter, copies at 0° and 90°: its pattern 0 is the raw
// pattern (bicubic at 0° is exact). The masks and correlators it was cut for, kept beside it.
struct RawBank {
  static constexpr int n = 16;
  PatternMask fine, half, coarse;
  FftCorrelator hc, cc;
  std::string why;
  std::unique_ptr<const PatternBank> bank;
  RawBank(const PatternImage& pattern, bool circular)
      : fine(n, circular, 8, 0), half(n / 2, circular), coarse(n / 4, circular),
        hc(good_fft_size(32), good_fft_size(32), half), cc(good_fft_size(16), good_fft_size(16), coarse) {
    PatternBankSpec spec;
    spec.pattern = pattern;
    spec.angle_step_deg = 90;
    spec.coarse_step_deg = 90;
    spec.coarse_factor = 4;
    bank = PatternBank::build(spec, {fine, half, hc, coarse, cc}, why);
  }
};

// The exact scorer for such a bank with an image (w×h) loaded as the ROI; the ROI's buffer
// lives as long as the scorer reads it.
struct LoadedScorer {
  std::vector<std::int32_t> roi;
  ExactScorer scorer;
  LoadedScorer(const RawBank& raw, const std::vector<std::uint16_t>& img, int w, int h)
      : roi(img.begin(), img.end()), scorer(raw.fine, 64) {
    scorer.load(roi.data(), w, h);
  }
};

// The exact scorer the tracker runs (walk, fit, start search) against a brute-force ZNCC at
// every displacement, circle and full square; a flat window scores 0, a window leaving the
// ROI has no score.
class ExactBrute : public ::testing::TestWithParam<bool> {};

TEST_P(ExactBrute, MatchesBruteForceEverywhere) {
  const bool circular = GetParam();
  const int n = 16, w = 40, h = 34;
  const auto img = texture(w, h, 7);
  const auto other = texture(n, n, 99);
  PatternImage pattern;
  pattern.width = pattern.height = n;
  pattern.pixels.resize(static_cast<std::size_t>(n) * n);
  std::vector<float> raw(pattern.pixels.size());
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      pattern.pixels[y * n + x] = static_cast<std::uint16_t>((4 * img[(9 + y) * w + 11 + x] + other[y * n + x]) / 5);
      raw[y * n + x] = pattern.pixels[y * n + x];
    }
  const RawBank raw_bank(pattern, circular);
  ASSERT_NE(raw_bank.bank, nullptr) << raw_bank.why;
  const auto& bank = raw_bank.bank;
  const PatternMask& fine = raw_bank.fine;
  LoadedScorer loaded(raw_bank, img, w, h);
  ExactScorer& scorer = loaded.scorer;
  double max_err = 0;
  for (int uy = 0; uy <= h - n; ++uy)
    for (int ux = 0; ux <= w - n; ++ux) {
      const double ref = brute_zncc(img, w, raw, n, fine, ux, uy);
      const float got = scorer.score(*bank, 0, ux, uy);
      max_err = std::max(max_err, std::fabs(ref - got));
    }
  EXPECT_LT(max_err, 1e-5);
  // The crop's own place scores highest.
  EXPECT_GT(scorer.score(*bank, 0, 11, 9), 0.9f);
  EXPECT_EQ(scorer.score(*bank, 0, w - n + 1, 0), -2.0f);
  EXPECT_EQ(scorer.score(*bank, 0, -1, 0), -2.0f);
  EXPECT_FALSE(scorer.parts(*bank, 0, 0, h - n + 1).inside);
  std::vector<std::int32_t> flat(loaded.roi.size(), 77);
  scorer.load(flat.data(), w, h);
  EXPECT_EQ(scorer.score(*bank, 0, 3, 3), 0.0f);
}
INSTANTIATE_TEST_SUITE_P(CircleAndSquare, ExactBrute, ::testing::Values(true, false));

// The background plane's products (SubpixelFit's nuisance ramp): Σ (x − mean x)·f and the same
// in y over the support, x and y in pattern widths from the centre, against a brute-force sum on
// the raw image (the regressors are centred, so any offset of f drops out); the nine places of
// plane_parts_3x3 against one place at a time; none where a place leaves the ROI.
TEST(ExactScorer, PlaneProductsMatchBruteForceAtNinePlaces) {
  const int n = 16, w = 40, h = 34;
  const auto img = texture(w, h, 11);
  PatternImage pattern;
  pattern.width = pattern.height = n;
  pattern.pixels.assign(img.begin(), img.begin() + n * n);  // any textured square
  const RawBank raw_bank(pattern, true);
  ASSERT_NE(raw_bank.bank, nullptr) << raw_bank.why;
  const auto& bank = raw_bank.bank;
  const PatternMask& fine = raw_bank.fine;
  const LoadedScorer loaded(raw_bank, img, w, h);
  const ExactScorer& scorer = loaded.scorer;
  const double c = (n - 1) / 2.0;
  double mx = 0, my = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (fine.inside(x, y)) mx += (x - c) / n, my += (y - c) / n;
  mx /= static_cast<double>(fine.count());
  my /= static_cast<double>(fine.count());
  const int ux = 9, uy = 7;
  PlaneParts nine[9];
  scorer.plane_parts_3x3(*bank, 0, ux, uy, nine);
  for (int oy = -1; oy <= 1; ++oy)
    for (int ox = -1; ox <= 1; ++ox) {
      double bx = 0, by = 0;
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          if (fine.inside(x, y)) {
            const double f = img[static_cast<std::size_t>(uy + oy + y) * w + ux + ox + x];
            bx += ((x - c) / n - mx) * f;
            by += ((y - c) / n - my) * f;
          }
      const PlaneParts one = scorer.plane_parts(*bank, 0, ux + ox, uy + oy, scorer.parts(*bank, 0, ux + ox, uy + oy));
      const PlaneParts& k = nine[(ox + 1) + 3 * (oy + 1)];
      ASSERT_TRUE(one.inside && k.inside);
      const double tol = 1e-4 * (std::fabs(bx) + std::fabs(by) + 1.0);
      EXPECT_NEAR(one.xf, bx, tol) << ox << "," << oy;
      EXPECT_NEAR(one.yf, by, tol) << ox << "," << oy;
      EXPECT_NEAR(k.xf, bx, tol) << ox << "," << oy;
      EXPECT_NEAR(k.yf, by, tol) << ox << "," << oy;
    }
  scorer.plane_parts_3x3(*bank, 0, 0, uy, nine);  // the column left of the window's is outside
  for (const PlaneParts& k : nine) EXPECT_FALSE(k.inside);
}

TEST(Zncc, TooSmallRegionIsRejected) {
  const PatternMask mask(16, true);
  FftCorrelator corr(32, 32, mask);
  const auto img = texture(10, 40, 1);
  EXPECT_FALSE(corr.load(img.data(), 10, 40, 10));
  EXPECT_EQ(corr.valid_w(), 0);
}

TEST(Rotation, CounterClockwiseOnScreen) {
  // A bright dot right of the centre (+x) must move up (−y) after +90° (README: Conventions).
  const int n = 21;
  std::vector<float> src(n * n, 0.0f), out(n * n);
  src[10 * n + 16] = 1.0f;
  rotate_pattern(src.data(), n, 90.0, out.data());
  EXPECT_NEAR(out[4 * n + 10], 1.0f, 1e-5);
  EXPECT_NEAR(out[10 * n + 16], 0.0f, 1e-5);
  rotate_pattern(src.data(), n, 0.0, out.data());
  for (int i = 0; i < n * n; ++i) EXPECT_NEAR(out[i], src[i], 1e-6);
}

// A shape mask's support as bands covers exactly its pixels, each once.
TEST(ShapeMask, BandsCoverTheBitmapExactly) {
  constexpr int n = 40;
  std::mt19937 rng(5);
  std::vector<std::uint8_t> in(n * n);
  // Blobs with holes and several runs per row: the merging must not lose or double a pixel.
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) in[y * n + x] = ((x / 5 + y / 7) % 3 != 0) && (rng() % 11 != 0);
  const std::vector<MaskBand> bands = bands_of(in.data(), n);
  std::vector<int> hits(n * n, 0);
  for (const MaskBand& b : bands)
    for (int y = b.y0; y <= b.y1; ++y)
      for (int x = b.x0; x <= b.x1; ++x) ++hits[y * n + x];
  for (int i = 0; i < n * n; ++i) ASSERT_EQ(hits[i], in[i] ? 1 : 0) << "pixel " << i % n << "," << i / n;
  EXPECT_LT(bands.size(), static_cast<std::size_t>(n * n / 4));  // rows were merged
}

// With a shape mask every angle's pattern is zero outside that angle's support, zero-mean and
// unit-norm inside it, and the support turns with the pattern.
TEST(ShapeMask, BankSupportTurnsWithThePattern) {
  constexpr int P = 64;
  const std::vector<std::uint16_t> tex = texture(P, P, 3);
  PatternImage pattern, shape;
  pattern.width = pattern.height = shape.width = shape.height = P;
  pattern.pixels.assign(tex.begin(), tex.end());
  shape.pixels.assign(P * P, 0);
  for (int y = 20; y < 44; ++y)
    for (int x = 8; x < 40; ++x) shape.pixels[y * P + x] = 255;  // off-centre bar
  PatternMask fine(P, true, 8, 4), half(P / 2, true, 8, 2), coarse(P / 8, true);
  FftCorrelator hc(good_fft_size(48), good_fft_size(48), half), cc(good_fft_size(20), good_fft_size(20), coarse);
  std::string why;
  const auto built = PatternBank::build(bank_spec(pattern, shape), {fine, half, hc, coarse, cc}, why);
  ASSERT_NE(built, nullptr) << why;
  const PatternBank& bank = *built;
  ASSERT_TRUE(bank.has_shape());
  for (int j : {0, 9, 18}) {  // 0°, 90°, 180°
    std::vector<int> in(P * P, 0);
    std::int64_t count = 0;
    for (int k = 0; k < bank.support_band_count(j); ++k) {
      const MaskBand& b = bank.support_bands(j)[k];
      for (int y = b.y0; y <= b.y1; ++y)
        for (int x = b.x0; x <= b.x1; ++x) in[y * P + x] = 1, ++count;
    }
    EXPECT_EQ(count, bank.support_count(j));
    EXPECT_NEAR(count, 24 * 32, 24 * 32 / 10);  // the bar, turned, still inside the circle
    double sum = 0, ss = 0;
    for (int i = 0; i < P * P; ++i) {
      const float v = bank.pattern(j)[i];
      if (!in[i]) {
        ASSERT_EQ(v, 0.0f) << "angle " << j << " pixel " << i;
      }
      sum += v;
      ss += static_cast<double>(v) * v;
    }
    EXPECT_NEAR(sum, 0.0, 1e-4);
    EXPECT_NEAR(ss, 1.0, 1e-4);
  }
  // The bar sits left of centre at 0°, right of it at 180°.
  EXPECT_TRUE(bank.support_bands(0)[0].x0 < P / 2 - 8);
  EXPECT_TRUE(bank.support_bands(18)[0].x1 > P / 2 + 8);
}

TEST(ShapeMask, WrongSizeOrEmptyMaskIsAClearError) {
  constexpr int P = 32;
  const std::vector<std::uint16_t> tex = texture(P, P, 4);
  PatternImage pattern, shape;
  pattern.width = pattern.height = P;
  pattern.pixels.assign(tex.begin(), tex.end());
  shape.width = shape.height = P / 2;
  shape.pixels.assign(P * P / 4, 255);
  PatternMask fine(P, true, 8, 4), half(P / 2, true, 8, 2), coarse(P / 8, true);
  FftCorrelator hc(good_fft_size(24), good_fft_size(24), half), cc(good_fft_size(8), good_fft_size(8), coarse);
  std::string why;
  EXPECT_EQ(PatternBank::build(bank_spec(pattern, shape), {fine, half, hc, coarse, cc}, why), nullptr);
  EXPECT_NE(why.find("16x16"), std::string::npos) << why;
  shape.width = shape.height = P;
  shape.pixels.assign(P * P, 0);  // nothing inside
  why.clear();
  EXPECT_EQ(PatternBank::build(bank_spec(pattern, shape), {fine, half, hc, coarse, cc}, why), nullptr);
  EXPECT_NE(why.find("shape mask"), std::string::npos) << why;
}
