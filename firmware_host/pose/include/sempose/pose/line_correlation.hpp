// The detector's line low-pass measured from the frames themselves (tracker.measure_detector_tau).
// Shot noise is white per pixel; a first-order low-pass along each scanned line (time constant
// τ, dwell d) makes the noise of neighbours on a line correlate by ρ = e^(−d/τ) while pixels of
// adjacent lines stay independent. The difference of two adjacent lines, z = y(j+1) − y(j),
// cancels the scene where it is smooth across lines and keeps the noise (variance 2v, still
// correlated by ρ along x); what the scene leaves in z (edges across the lines) is removed by the
// same lag-1 product across lines of the along-line differences, where the noise has no share:
//   ρ = (Σ z(i)·z(i+1) − Σ Δx(j)·Δx(j+1)) / Σ z(i)²,   Δx(j) = y(i+1, j) − y(i, j).
// Closed form, one pass, no allocation. Real micrograph (lamella_on_post_eb.pgm, 192² crops,
// Poisson, 20 crops): bias ≤ 0.013 in ρ at 20 e⁻/px and ≤ 0.003 at ≤ 6 e⁻/px for τ 0–4 px; a
// flat scene ≤ 0.002 (test_line_correlation.cpp).
#pragma once

#include <cstddef>
#include <cstdint>

namespace sempose::pose {

// One frame's sums over line pairs (j, j+1), j = 0, row_step, 2·row_step, …; the first
// kSkipPx pixels of each line are left out (the scan generator's line start: flyback, the
// low-pass settling).
//
// Whether the noise dominates (the gate): the statistic is only as good as the noise's share of
// Σ z². What the scene leaves in z is not noise (noise-free frames read their edges as lag: a
// sharp needle 1.31 px), and it cannot be told from noise by z alone. The second difference
// across lines, w = y(j+2) − 2y(j+1) + y(j), measures the noise's variance v without the
// detector's correlation (it mixes pixels of one column, E w² = 6v) and cancels the scene's
// gradients across lines; its mean |w| (Immerkær's estimator, robust to the sparse edges that
// dominate a scene's Σ z²) predicts the noise's part of Σ z², 2v per pair:
//   noise_share = 2·(π/2)·(mean |w|)²/6 / (Σ z²/pairs),
// ~1 where the noise dominates, → 0 on noise-free or very high-dose structure.
//
// Whether it is a detector's low-pass at all (the lag-2 check): a causal first-order low-pass
// along the line makes the noise's correlation fall as ρ(k) = ρ^k, so ρ2 = ρ1². What else
// correlates z along a line breaks that in its own way: a dropped (black) line leaves its
// neighbour's scene in z, smooth along x, so ρ2 ≈ ρ1 (every 4th line dropped: ρ1 0.65–0.79,
// ρ2 − ρ1² +0.10…+0.25). ρ2 is read as ρ1 is, with the lag-2 products: z(i)·z(i+2) and across
// lines Δ2x(j)·Δ2x(j+1), Δ2x(j) = y(i+2, j) − y(i, j). Only that side is checked: the scene's
// leak pulls ρ2 below ρ1² — what is left of it in the sums is Σ (b(i) − a(i+k))(b(i+k) − a(i)),
// the product of the two diagonal differences, −g² a pixel on a gradient g along x, about twice
// as much at lag 2 as at lag 1 — and grows with the dose: the simulator's targets through a real
// low-pass of τ 1–4 px read −0.11…−0.15 at 20 e⁻/px, as low as a symmetric blur of the noise
// ([1 2 1]/4: −0.28; a Gaussian's ρ2 = ρ1⁴), so a blur cannot be told from a real detector at
// high dose this way (a lower bound tried: it left a real τ 4 px lag in, 5 false poses).
struct LineCorrelationSums {
  double along = 0;   // Σ z(i)·z(i+1)
  double across = 0;  // Σ Δx(j)·Δx(j+1)
  double along2 = 0;   // Σ z(i)·z(i+2)
  double across2 = 0;  // Σ Δ2x(j)·Δ2x(j+1)
  double power = 0;   // Σ z(i)²
  double second_abs = 0;  // Σ |w(i)|
  std::int64_t pairs = 0;
  static constexpr int kSkipPx = 8;
  bool valid() const noexcept { return pairs > 0 && power > 0; }
  double rho() const noexcept { return valid() ? (along - across) / power : 0.0; }
  double rho2() const noexcept { return valid() ? (along2 - across2) / power : 0.0; }
  // The noise variance of one pixel mean |w| predicts, (π/2)(mean |w|)²/6, and its share of Σ z².
  double noise_var() const noexcept;
  double noise_share() const noexcept;
  // The gate: noise_share ≥ min_share (a frame's: DetectorTauEstimator::kMinNoiseShare) and
  // noise_var ≥ kMinNoiseVar.
  bool noise_dominates(double min_share) const noexcept;
};

// Every row_step-th pair of lines of a w × h image (stride in pixels); row_step ≥ 1. A band:
// at most max_pairs pairs from line first_line on (the tracker reads a band a frame).
LineCorrelationSums line_correlation_sums(const std::uint16_t* px, int w, int h, std::ptrdiff_t stride,
                                          int row_step, int first_line = 0, int max_pairs = 1 << 30) noexcept;
// The row step that keeps a w × h frame's sums at about kPairBudget pairs (2: every line of a
// 192² ROI once; a 640 × 480 field every 16th).
int line_correlation_row_step(int w, int h) noexcept;

// The pairs of a band of a w-wide frame: ~kPairBudget / 8 products (a 192² ROI: 12 pairs, its
// every line in 8 frames; 1.35 µs a band, 10.5 µs the whole ROI, standalone on this machine).
int line_correlation_band_pairs(int w) noexcept;

// ρ of a w × h image (a pattern at setup) read in 16 × 16 px tiles: the median over the tiles
// whose noise dominates their structure (the frames' gate). A pattern's structure fills most of
// it, and read whole a lag-free pattern recorded at 8x the dose read its edges as ρ 0.31–0.57
// (the held-out needle's, share 0.16–0.36). ≥ kLagFreeRho from ≥ kMinPatternTiles open tiles,
// else 0 — lag-free, or no lag that can be told (a noise-free crop: every tile closed). Setup
// only (allocates).
double pattern_line_rho(const std::uint16_t* px, int w, int h);
// The same reading with how many tiles it rests on: the median ρ of the open tiles as read
// (capped at kMaxRho, not yet rounded to lag-free), readable() from kMinPatternTiles on. A
// told τ is checked against it (DetectorTauEstimator::told_disagrees), so "cannot be told"
// must not read as "lag-free".
struct PatternLineRho {
  double rho = 0;
  int open_tiles = 0;
  bool readable() const noexcept;
  double lag_rho() const noexcept;  // ρ as a lag: readable and ≥ kLagFreeRho, else 0
};
PatternLineRho read_pattern_line_rho(const std::uint16_t* px, int w, int h);

// The running estimate of ρ over the frames whose fit was good, weighted by their pairs (a
// frame's share falls as pairs accumulate, down to 1/kMemoryFrames of an ROI frame's pairs). Two
// estimates: one in the frames' pixels as read, one kept at a reference dwell (the first frame's;
// ρ at dwell d is ρ_ref^(d/d_ref)). The second is used only once it predicts the readings better
// than the first: a replay reports the governor's dwell, not the one its frames were recorded at,
// and there ρ does not follow the dwell reported. Frames of unknown dwell are taken as at the
// reference. RT-safe.
class DetectorTauEstimator {
 public:
  static constexpr std::int64_t kPairBudget = 18432;  // a 192² ROI's every line once
  static constexpr double kMemoryFrames = 64;         // ROI frames' worth of pairs the estimate keeps
  static constexpr double kSettledFrames = 16;        // ROI frames' worth before it is reported settled
  // Below this ρ (τ < 0.33 px, lag < 0.053 px) the detector is taken as fast: no lag. The
  // estimate's own bias on a real micrograph's structure is ~0.013 at 20 e⁻/px.
  static constexpr double kFastRho = 0.05;
  static constexpr double kMaxRho = 0.9;  // τ 9.5 px, lag 9 px: beyond it the estimate is capped
  // The gate: a reading counts only where the noise's predicted share of Σ z² is at least this
  // (LineCorrelationSums::noise_share). White Poisson noise reads 0.79–0.86 at 1 e⁻/px (its
  // skew: mean |w| reads low), 0.89–1.07 from 2.5 e⁻/px on, a band or a whole ROI, with or
  // without structure; a noise-free scene of sharp edges 0.03, and read raw ρ 0.17 at τ 0
  // (test_line_correlation.cpp). A real micrograph's own noise dominates it too (0.86–0.97).
  static constexpr double kMinNoiseShare = 0.7;
  // … and the noise at least one grey level (its variance 12x the levels' rounding, 1/12): a flat
  // noise-free band's rounding is deterministic, not noise (a ramp's reads ρ −1).
  static constexpr double kMinNoiseVar = 1.0;
  // A pattern's reading needs this many open tiles (a tile's ρ is good to ~0.07, the median of
  // 6 to ~0.035): the held-out needle's pattern of 10 frames at the tracking dwell (2.5 e⁻/px,
  // τ 2 px) opens ~12 of 64; lag-free ones recorded at 8x the dose 0–1.
  static constexpr int kMinPatternTiles = 6;
  // A pattern (pattern_line_rho) reading below this is lag-free: a real micrograph's own noise
  // reads 0.09–0.10 (lamella_on_post_eb.pgm, whose lag frames rendered from it carry too).
  static constexpr double kLagFreeRho = 0.15;
  // A pattern's and the frames' ρ closer than this are one detector at one dwell: no lag between
  // them. A pattern's reading carries its structure's leak (the held-out needle: +0.017, which at
  // ρ 0.6 is 0.1 px of lag that is not there).
  static constexpr double kSameDetectorRho = 0.03;
  // A told τ (tracker.detector_tau_ns, a set's dwell_ns) and what the noise shows disagree when
  // their ρ differ by at least kToldRhoTolerance and the lags by at least kToldLagTolerancePx.
  // The readings' own error: a pattern's median of ≥ 6 tiles ~0.035 plus its structure's leak
  // (+0.017), the frames' estimate in the tracker ≤ 0.03 low at τ 4 px (3.45 px read for 4);
  // 0.1 is ~3x either. The lag's: what the measured correction itself misses (it overshoots
  // by 0.2–0.9 px at τ 2–4 px, the shift model), so a told value nearer than that is kept.
  static constexpr double kToldRhoTolerance = 0.1;
  static constexpr double kToldLagTolerancePx = 0.5;
  // The frames check a told τ from this many ROI frames' worth of kept pairs on (~18k products,
  // ~8 accepted frames' bands: the statistical SD of ρ ~0.007, 14x below kToldRhoTolerance),
  // not kSettledFrames (~128 frames of bands).
  static constexpr double kToldCheckFrames = 1;
  static bool told_disagrees(double told_rho, double measured_rho) noexcept;
  // The lag-2 check (LineCorrelationSums): the estimate is a detector's low-pass only while its
  // δ = ρ2 − ρ1² (the readings' mean, weighted as ρ's) is at most kLag2Bias + kLag2NoiseSigmas ·
  // kLag2NoiseSd / √pairs. A real low-pass of τ 0–4 px (flat and micrograph scenes, 1–20 e⁻/px,
  // 8 frames of bands, test_line_correlation.cpp) reads δ −0.025…+0.006, in the tracker down to
  // −0.15 (the scene's leak, below); a band's δ scatters with SD ~0.025 at ~2.2k pairs
  // (kLag2NoiseSd / √pairs). Every 4th line dropped reads δ +0.10…+0.25 (τ 0) and +0.04…+0.10
  // (τ 1 px), in the tracker +0.17…+0.19 at 20 e⁻/px.
  static constexpr double kLag2Bias = 0.04;
  static constexpr double kLag2NoiseSd = 1.2;
  static constexpr double kLag2NoiseSigmas = 3;
  // The lag ρ/(1 − ρ) px of a line correlation ρ (0 below kFastRho, capped at kMaxRho).
  static double lag_of_rho(double rho) noexcept;

  // This frame's reading: lag_px() includes it from now on; keep() makes it part of the estimate
  // (a frame whose fit was good), otherwise the next reading replaces it. A reading below
  // kMinNoiseShare is none (its scene, not its noise, would be read as lag).
  void read(const LineCorrelationSums& s, double dwell_ns) noexcept;
  void keep() noexcept;
  void reset() noexcept { *this = DetectorTauEstimator{}; }

  // The estimate (with the pending reading) at dwell_ns (≤ 0: as read); 0 before any reading.
  double rho_at(double dwell_ns) const noexcept;
  // The lag e^(−d/τ)/(1 − e^(−d/τ)) = ρ/(1 − ρ) px at dwell_ns; 0 below kFastRho or where the
  // readings are not a low-pass's (consistent()).
  double lag_px(double dwell_ns) const noexcept;
  // τ in px at the reference dwell and in ns (0: fast, not consistent(), or the dwell not known).
  double tau_px() const noexcept;
  double tau_ns() const noexcept;
  double reference_dwell_ns() const noexcept { return ref_dwell_ns_; }
  // A reading passed the gate (kept, or this frame's): lag_px() is the frames' measured lag.
  bool has_reading() const noexcept { return weight_ > 0 || pending_weight_ > 0; }
  bool settled() const noexcept { return weight_ >= kSettledFrames * kPairBudget; }
  double frames_kept() const noexcept { return weight_ / kPairBudget; }
  // ρ follows the frames' dwell as reported (the readings say so); false: ρ as read.
  bool follows_dwell() const noexcept { return miss_mapped_ < miss_read_; }
  // The lag-2 check: ρ2 − ρ1² of the readings (with the pending one), and whether it says a
  // first-order low-pass along the line (true before any reading). Not consistent: lag_px() 0.
  double lag2_excess() const noexcept { return blended(delta_, pending_delta_); }
  bool consistent() const noexcept;

 private:
  double mapped(double rho, double from_dwell, double to_dwell) const noexcept;
  double blended(double kept, double pending) const noexcept;
  double rho_ = 0, rho_read_ = 0, weight_ = 0;  // kept estimates (at the reference dwell; as read), their weight in pairs
  double pending_rho_ = 0, pending_read_ = 0, pending_dwell_ = 0, pending_weight_ = 0;
  double delta_ = 0, pending_delta_ = 0;  // ρ2 − ρ1² kept, and this frame's
  double ref_dwell_ns_ = 0;
  // How far each estimate missed the kept readings (squared, ~kMemoryFrames readings' memory).
  double miss_mapped_ = 0, miss_read_ = 0;
};

}  // namespace sempose::pose
