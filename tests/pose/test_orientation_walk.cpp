// The walk, the fit, the sweep and the start search wired as the tracker wires them, on a
// synthetic noise-free scene: a smooth analytic texture rendered exactly at a known pose (no
// interpolation), so each stage's answer is known.
#pragma GCC diagnostic ignored "-Wnull-dereference"  // GCC 12 false positive inside gtest.h
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "sempose/pose/angle_sweep.hpp"
#include "sempose/pose/engine_sizes.hpp"
#include "sempose/pose/orientation_walk.hpp"
#include "sempose/pose/roi_loader.hpp"
#include "sempose/pose/scale_probe.hpp"
#include "sempose/pose/start_search.hpp"
#include "analytic_scene.hpp"

using namespace sempose;
using namespace sempose::pose;

namespace {

constexpr int kPattern = 32;
constexpr double kStepDeg = 2.0;

// The noise-free target as the walk's tests see it.
std::vector<std::uint16_t> render(int w, int h, double cx, double cy, double phi_deg) {
  return test::render_analytic(w, h, cx, cy, phi_deg);
}

// The tracker's stages for a 32 px pattern, 64 px ROI, 160×128 field, 2° steps, no prefilter.
struct Stages {
  config::TrackerConfig cfg;
  EngineSizes sizes;
  AngleGrid angles{180, kStepDeg};
  PatternMask fine{kPattern, true, 8, 2}, half_mask{kPattern / 2, true, 8, 1}, coarse_mask{kPattern / 4, true};
  std::unique_ptr<FftCorrelator> half, coarse;
  std::unique_ptr<ExactScorer> scorer;
  std::unique_ptr<RoiLoader> loader;
  std::unique_ptr<RoiRescaler> rescaler;
  std::unique_ptr<ScaleProbe> probe;
  std::unique_ptr<ScaleEvidenceCheck> evidence;
  std::unique_ptr<CorrelationMaps> maps;
  SubpixelFit fit{true, true};
  std::unique_ptr<OrientationWalk> walk;
  std::unique_ptr<AngleSweep> sweep;
  std::unique_ptr<StartSearch> search;
  std::unique_ptr<const PatternBank> bank;

  Stages() {
    cfg.pattern_size_px = kPattern;
    cfg.roi_size_px = 64;
    cfg.angle_step_deg = kStepDeg;
    cfg.prefilter_passes = 0;
    cfg.search_downsample = 4;
    sizes = EngineSizes::of(cfg, kPattern, 160, 128);
    half = std::make_unique<FftCorrelator>(sizes.half_fft_px, sizes.half_fft_px, half_mask);
    coarse = std::make_unique<FftCorrelator>(good_fft_size(sizes.coarse_max_w), good_fft_size(sizes.coarse_max_h), coarse_mask);
    scorer = std::make_unique<ExactScorer>(fine, sizes.roi_fft_px);
    loader = std::make_unique<RoiLoader>(0, sizes.roi_fft_px, *scorer, *half);
    rescaler = std::make_unique<RoiRescaler>(sizes.roi_fft_px);
    probe = std::make_unique<ScaleProbe>(*scorer);
    evidence = std::make_unique<ScaleEvidenceCheck>(*scorer);
    maps = std::make_unique<CorrelationMaps>(static_cast<std::size_t>(sizes.half_fft_px) * sizes.half_fft_px);
    walk = std::make_unique<OrientationWalk>(*scorer, fit, angles);
    sweep = std::make_unique<AngleSweep>(*half, *walk, angles, *maps);
    search = std::make_unique<StartSearch>(cfg, sizes, angles, *coarse, nullptr, *half, *loader, *rescaler, *probe, *evidence, *walk, *sweep, *maps);
    PatternBankSpec spec;
    const std::vector<std::uint16_t> pattern = render(kPattern, kPattern, (kPattern - 1) / 2.0, (kPattern - 1) / 2.0, 0);
    spec.pattern = {kPattern, kPattern, pattern};
    spec.angle_step_deg = kStepDeg;
    spec.coarse_step_deg = cfg.search_angle_step_deg;
    spec.coarse_factor = cfg.search_downsample;
    std::string why;
    bank = PatternBank::build(spec, {fine, half_mask, *half, coarse_mask, *coarse}, why);
    EXPECT_NE(bank, nullptr) << why;
  }
};

// The pose a measurement stands for, given the ROI's top-left in the field.
double pose_x(const Measurement& m, int roi_x) { return roi_x + m.ux + m.dx + (kPattern - 1) / 2.0; }
double pose_y(const Measurement& m, int roi_y) { return roi_y + m.uy + m.dy + (kPattern - 1) / 2.0; }
double pose_phi(const Measurement& m) { return (m.j + m.dj) * kStepDeg; }

}  // namespace

TEST(OrientationWalk, WalksFromAWrongAngleToTheTargetAndFits) {
  Stages st;
  const double cx = 13 + 15.5 + 0.3, cy = 9 + 15.5 - 0.2, phi = 20.6;
  const auto roi = render(64, 64, cx, cy, phi);
  ASSERT_TRUE(st.loader->load(roi.data(), 64, 64, 64, 16));
  const int j_start = 7;  // 14°: 6.6° off
  st.half->correlate(st.bank->spectrum(j_start), st.maps->work());
  const Peak pk = find_peak(st.maps->work(), st.half->valid_w(), st.half->valid_h());
  const Measurement m = st.walk->measure(*st.bank, j_start, pk, 8);
  ASSERT_TRUE(m.valid);
  EXPECT_FALSE(m.unsettled);
  EXPECT_EQ(m.j, 10);
  EXPECT_NEAR(pose_x(m, 0), cx, 0.1);
  EXPECT_NEAR(pose_y(m, 0), cy, 0.1);
  EXPECT_NEAR(pose_phi(m), phi, 0.3);
  EXPECT_GT(m.score, 0.95f);
  EXPECT_GT(m.steps, 19);  // at least the fit's 19 exact scores
  // A walk bounded to 2 moves cannot get there: reported unsettled.
  EXPECT_TRUE(st.walk->measure(*st.bank, j_start, pk, 2).unsettled);
}

// The probe's reading takes its three stretches in one pass over the window: it must be the
// parabola through the three scores score() gives one at a time, to the bit.
TEST(ScaleProbe, ReadIsTheParabolaThroughItsThreeScores) {
  Stages st;
  for (const double phi : {20.6, 97.0}) {
    const double cx = 13 + 15.5 + 0.3, cy = 9 + 15.5 - 0.2;
    const auto roi = render(64, 64, cx, cy, phi);
    ASSERT_TRUE(st.loader->load(roi.data(), 64, 64, 64, 16));
    const int j = static_cast<int>(std::lround(phi / kStepDeg));
    st.half->correlate(st.bank->spectrum(j), st.maps->work());
    const Peak pk = find_peak(st.maps->work(), st.half->valid_w(), st.half->valid_h());
    const Measurement m = st.walk->measure(*st.bank, j, pk, 8);
    ASSERT_TRUE(m.valid);
    const double k = ScaleProbe::kStep;
    for (const int stride : {ScaleProbe::kStride, 1}) {
      const double lo = st.probe->score(*st.bank, m, 1.0 - k, 1.0 - k, stride);
      const double mid = st.probe->score(*st.bank, m, 1.0, 1.0 - k, stride);
      const double hi = st.probe->score(*st.bank, m, 1.0 + k, 1.0 - k, stride);
      ASSERT_GT(lo, -1.5);
      ASSERT_GT(mid, -1.5);
      ASSERT_GT(hi, -1.5);
      if (stride != ScaleProbe::kStride) continue;  // read() uses kStride
      const ScaleReading r = st.probe->read(*st.bank, m);
      ASSERT_TRUE(r.valid);
      const double curv = lo - 2.0 * mid + hi;
      const double expected = curv < 0 ? 1.0 + std::clamp(0.5 * (lo - hi) / curv, -1.0, 1.0) * k : (hi > lo ? 1.0 + k : 1.0 - k);
      EXPECT_EQ(r.factor, expected) << phi;
    }
  }
}

TEST(AngleSweep, FindsTheAngleFarOutsideTheWalksReach) {
  Stages st;
  const double cx = 30.5, cy = 33.5, phi = -40.0;
  const auto roi = render(64, 64, cx, cy, phi);
  ASSERT_TRUE(st.loader->load(roi.data(), 64, 64, 64, 16));
  const Measurement m = st.sweep->sweep(*st.bank, st.angles.index_of(-10.0), 40, 6, 4);
  EXPECT_NEAR(pose_phi(m) - 360.0, phi, 0.3);
  EXPECT_NEAR(pose_x(m, 0), cx, 0.1);
  EXPECT_NEAR(pose_y(m, 0), cy, 0.1);
}

TEST(StartSearch, FindsTheTargetOnTheFullField) {
  Stages st;
  const double cx = 97.3, cy = 52.8, phi = 64.0;
  const auto field = render(160, 128, cx, cy, phi);
  int rx = -1, ry = -1;
  double scale = 0;
  const Measurement m = st.search->search(*st.bank, field.data(), 160, 128, 16, {}, {}, rx, ry, scale);
  ASSERT_TRUE(m.valid);
  EXPECT_NEAR(scale, 1.0, 0.03) << "searched over 0.75–1.33, found at its size";
  EXPECT_NEAR(pose_x(m, rx), cx, 0.15);
  EXPECT_NEAR(pose_y(m, ry), cy, 0.15);
  EXPECT_NEAR(pose_phi(m), phi, 0.3);
  // A flat field has nothing to find.
  const std::vector<std::uint16_t> flat(160 * 128, 500);
  EXPECT_FALSE(st.search->search(*st.bank, flat.data(), 160, 128, 16, {}, {}, rx, ry, scale).valid);
}

TEST(StartSearch, AScoreTieGoesToTheAngleNearTheLastTrackedOne) {
  Stages st;
  Measurement coarse_choice, opposite;
  coarse_choice.score = 0.80f;
  coarse_choice.j = 10;   // 20°
  opposite.score = 0.81f; // within the tie band
  opposite.j = 100;       // 200°
  EXPECT_FALSE(st.search->prefer_opposite(coarse_choice, opposite, {}));
  EXPECT_TRUE(st.search->prefer_opposite(coarse_choice, opposite, {true, -150.0}));
  EXPECT_FALSE(st.search->prefer_opposite(coarse_choice, opposite, {true, 25.0}));
  opposite.score = 0.85f;  // a clear lead wins regardless
  EXPECT_TRUE(st.search->prefer_opposite(coarse_choice, opposite, {true, 25.0}));
}

// The scale prior's evidence check on exact scenes: the target stretched by 1.25 as a whole
// (a rigid target at another scale) is clear evidence for 1.25 against 1; the same stretch on
// the target's right part only (the body fits at 1, a part moved outwards: a gripper's jaws)
// fits a stretched pattern better but is not; noise as large as the gain is not either.
TEST(ScaleEvidence, RigidStretchIsClearPartOrNoiseIsNot) {
  Stages st;
  const double c = 31.5;
  const test::AnalyticTexture tex;
  std::uint32_t lcg = 12345;
  auto scene = [&](double right_part_scale, double left_part_scale, double noise) {
    std::vector<std::uint16_t> roi(64 * 64);
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        const double dx = x - c, dy = y - c, s = dx > 2 ? right_part_scale : left_part_scale;
        lcg = lcg * 1664525u + 1013904223u;
        const double n = noise * ((lcg >> 8) / 16777216.0 - 0.5);
        const double v = 20000 + tex(dx / s, dy / s) + n;  // noise about a raised level: nothing clipped
        roi[static_cast<std::size_t>(y) * 64 + x] = static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0, 65535.0)));
      }
    return roi;
  };
  Measurement at;
  at.valid = true;
  at.ux = at.uy = static_cast<int>(c - (kPattern - 1) / 2.0);
  auto check = [&](const std::vector<std::uint16_t>& roi) {
    EXPECT_TRUE(st.loader->load(roi.data(), 64, 64, 64, 16));
    return st.evidence->compare(*st.bank, at, 1.25, at, 1.0);
  };
  const ScaleEvidence rigid = check(scene(1.25, 1.25, 0));
  ASSERT_TRUE(rigid.valid);
  EXPECT_TRUE(rigid.clear) << rigid.r_away << " vs " << rigid.r_expected << " rho " << rigid.rho;
  const ScaleEvidence part = check(scene(1.25, 1.0, 0));
  ASSERT_TRUE(part.valid);
  EXPECT_GT(part.r_away, part.r_expected) << "the moved part does fit a stretched pattern better";
  EXPECT_FALSE(part.clear) << part.r_away << " vs " << part.r_expected << " rho " << part.rho;
  const ScaleEvidence noisy = check(scene(1.25, 1.25, 5000));
  ASSERT_TRUE(noisy.valid);
  EXPECT_LT(noisy.r_away - noisy.r_expected, ScaleEvidenceCheck::kSigmas * noisy.noise) << "within noise";
  EXPECT_FALSE(noisy.clear);
}
