#include "sempose/pose/line_correlation.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace sempose::pose {

LineCorrelationSums line_correlation_sums(const std::uint16_t* px, int w, int h, std::ptrdiff_t stride,
                                          int row_step, int first_line, int max_pairs) noexcept {
  LineCorrelationSums s;
  const int i0 = LineCorrelationSums::kSkipPx;
  if (px == nullptr || w < i0 + 2 || h < 3 || row_step < 1 || first_line < 0) return s;
  // Per line pair in float (the differences are exact, a line's sums of ≤ 1024 products good to
  // ~1e-5, far below the estimate's noise; vectorised), added to the doubles once a pair. The
  // gate's third line is j + 2, so the last pair is the one before the last line.
  int n = 0;
  for (int j = first_line; j + 2 < h && n < max_pairs; j += row_step, ++n) {
    const std::uint16_t* a = px + static_cast<std::ptrdiff_t>(j) * stride;
    const std::uint16_t* b = a + stride;
    const std::uint16_t* c = b + stride;
    float along = 0, across = 0, power = 0, second = 0, along2 = 0, across2 = 0;
    // The lag-2 products up to the line's last but one pixel, the lag-1 ones on to its last.
#pragma omp simd reduction(+ : along, across, power, second, along2, across2)
    for (int i = i0; i < w - 2; ++i) {
      const float z0 = static_cast<float>(b[i]) - static_cast<float>(a[i]);
      const float z1 = static_cast<float>(b[i + 1]) - static_cast<float>(a[i + 1]);
      const float z2 = static_cast<float>(b[i + 2]) - static_cast<float>(a[i + 2]);
      const float dxa = static_cast<float>(a[i + 1]) - static_cast<float>(a[i]);
      const float dxb = static_cast<float>(b[i + 1]) - static_cast<float>(b[i]);
      const float dxa2 = static_cast<float>(a[i + 2]) - static_cast<float>(a[i]);
      const float dxb2 = static_cast<float>(b[i + 2]) - static_cast<float>(b[i]);
      along += z0 * z1;
      across += dxa * dxb;
      along2 += z0 * z2;
      across2 += dxa2 * dxb2;
      power += z0 * z0;
      second += std::fabs(static_cast<float>(c[i]) - static_cast<float>(b[i]) - z0);
    }
    {
      const int i = w - 2;
      const float z0 = static_cast<float>(b[i]) - static_cast<float>(a[i]);
      const float z1 = static_cast<float>(b[i + 1]) - static_cast<float>(a[i + 1]);
      along += z0 * z1;
      across += (static_cast<float>(a[i + 1]) - static_cast<float>(a[i])) * (static_cast<float>(b[i + 1]) - static_cast<float>(b[i]));
      power += z0 * z0;
      second += std::fabs(static_cast<float>(c[i]) - static_cast<float>(b[i]) - z0);
    }
    s.along += along;
    s.across += across;
    s.along2 += along2;
    s.across2 += across2;
    s.power += power;
    s.second_abs += second;
    s.pairs += w - 1 - i0;
  }
  return s;
}

double LineCorrelationSums::noise_var() const noexcept {
  if (!valid()) return 0.0;
  const double mean_abs = second_abs / static_cast<double>(pairs);
  return M_PI / 2.0 * mean_abs * mean_abs / 6.0;  // E|w| = σ_w √(2/π), σ_w² = 6v
}

double LineCorrelationSums::noise_share() const noexcept {
  return valid() ? 2.0 * noise_var() * static_cast<double>(pairs) / power : 0.0;
}

bool LineCorrelationSums::noise_dominates(double min_share) const noexcept {
  return noise_share() >= min_share && noise_var() >= DetectorTauEstimator::kMinNoiseVar;
}

int line_correlation_row_step(int w, int h) noexcept {
  const std::int64_t pixels = static_cast<std::int64_t>(std::max(w, 0)) * std::max(h, 0);
  // A pair of lines every 2nd line uses every line once (a 192² ROI: 96 pairs, ~17.5k products).
  return static_cast<int>(std::max<std::int64_t>(2, pixels / DetectorTauEstimator::kPairBudget));
}

int line_correlation_band_pairs(int w) noexcept {
  const int products = std::max(1, w - 1 - LineCorrelationSums::kSkipPx);
  return static_cast<int>(std::max<std::int64_t>(1, DetectorTauEstimator::kPairBudget / 8 / products));
}

bool PatternLineRho::readable() const noexcept { return open_tiles >= DetectorTauEstimator::kMinPatternTiles; }

double PatternLineRho::lag_rho() const noexcept {
  return readable() && rho >= DetectorTauEstimator::kLagFreeRho ? rho : 0.0;
}

double pattern_line_rho(const std::uint16_t* px, int w, int h) { return read_pattern_line_rho(px, w, h).lag_rho(); }

PatternLineRho read_pattern_line_rho(const std::uint16_t* px, int w, int h) {
  constexpr int kTile = 16, skip = LineCorrelationSums::kSkipPx;
  // A tile's sub-image starts kSkipPx columns early (its first pixels are skipped as a line's
  // start) and 2 lines long (the gate's third line): kTile × kTile products each. The median
  // over the open tiles: a tile with an edge that passed the gate by its own noise would weigh
  // by its large Σ z² in a sum (a disk's rim pulled a τ 2 px pattern's 0.607 to 0.43).
  std::vector<double> open;
  for (int y0 = 0; y0 + 2 < h; y0 += kTile)
    for (int x0 = skip; x0 + 1 < w; x0 += kTile) {
      const int tw = std::min(kTile + skip + 1, w - (x0 - skip)), th = std::min(kTile + 2, h - y0);
      const LineCorrelationSums t =
          line_correlation_sums(px + static_cast<std::ptrdiff_t>(y0) * w + (x0 - skip), tw, th, w, 1);
      if (t.noise_dominates(DetectorTauEstimator::kMinNoiseShare)) open.push_back(t.rho());
    }
  PatternLineRho r;
  r.open_tiles = static_cast<int>(open.size());
  if (!r.readable()) return r;
  std::nth_element(open.begin(), open.begin() + static_cast<std::ptrdiff_t>(open.size() / 2), open.end());
  r.rho = std::min(open[open.size() / 2], DetectorTauEstimator::kMaxRho);
  return r;
}

double DetectorTauEstimator::lag_of_rho(double rho) noexcept {
  if (!(rho >= kFastRho)) return 0.0;
  const double r = std::min(rho, kMaxRho);
  return r / (1.0 - r);
}

bool DetectorTauEstimator::told_disagrees(double told_rho, double measured_rho) noexcept {
  return std::fabs(told_rho - measured_rho) >= kToldRhoTolerance &&
         std::fabs(lag_of_rho(told_rho) - lag_of_rho(measured_rho)) >= kToldLagTolerancePx;
}

double DetectorTauEstimator::mapped(double rho, double from_dwell, double to_dwell) const noexcept {
  // ρ = e^(−d/τ): at another dwell ρ^(d'/d). A dwell not known is taken as the other one.
  if (!(rho > 0) || !(from_dwell > 0) || !(to_dwell > 0)) return rho;
  return std::pow(rho, to_dwell / from_dwell);
}

void DetectorTauEstimator::read(const LineCorrelationSums& s, double dwell_ns) noexcept {
  pending_weight_ = 0;
  if (!s.noise_dominates(kMinNoiseShare)) return;
  const double rho = s.rho();
  if (!std::isfinite(rho)) return;
  if (!(ref_dwell_ns_ > 0) && weight_ == 0 && dwell_ns > 0) ref_dwell_ns_ = dwell_ns;
  // Clamped: a torn frame's sums can give |ρ| > 1; one frame must not carry the estimate far.
  pending_read_ = std::clamp(rho, -1.0, 0.999);
  pending_rho_ = mapped(pending_read_, dwell_ns, ref_dwell_ns_);
  pending_dwell_ = dwell_ns;
  pending_weight_ = static_cast<double>(s.pairs);
  const double rho2 = s.rho2();
  pending_delta_ = std::isfinite(rho2) ? std::clamp(rho2, -1.0, 1.0) - pending_read_ * pending_read_ : 0.0;
}

void DetectorTauEstimator::keep() noexcept {
  if (!(pending_weight_ > 0)) return;
  if (weight_ > 0) {
    // Which estimate foresaw this reading: the one kept at the reference dwell, or the one as read.
    const double decay = 1.0 - 1.0 / kMemoryFrames;
    const double m = pending_read_ - mapped(rho_, ref_dwell_ns_, pending_dwell_), r = pending_read_ - rho_read_;
    miss_mapped_ = decay * miss_mapped_ + m * m;
    miss_read_ = decay * miss_read_ + r * r;
  }
  rho_ = blended(rho_, pending_rho_);
  rho_read_ = blended(rho_read_, pending_read_);
  delta_ = blended(delta_, pending_delta_);
  weight_ = std::min(weight_ + pending_weight_, kMemoryFrames * static_cast<double>(kPairBudget));
  pending_weight_ = 0;
}

double DetectorTauEstimator::blended(double kept, double pending) const noexcept {
  const double w = weight_ + pending_weight_;
  return w > 0 ? (kept * weight_ + pending * pending_weight_) / w : 0.0;
}

double DetectorTauEstimator::rho_at(double dwell_ns) const noexcept {
  return follows_dwell() ? mapped(blended(rho_, pending_rho_), ref_dwell_ns_, dwell_ns) : blended(rho_read_, pending_read_);
}

bool DetectorTauEstimator::consistent() const noexcept {
  const double pairs = weight_ + pending_weight_;
  if (!(pairs > 0)) return true;
  return lag2_excess() <= kLag2Bias + kLag2NoiseSigmas * kLag2NoiseSd / std::sqrt(pairs);
}

double DetectorTauEstimator::lag_px(double dwell_ns) const noexcept {
  return consistent() ? lag_of_rho(rho_at(dwell_ns)) : 0.0;
}

double DetectorTauEstimator::tau_px() const noexcept {
  if (!consistent()) return 0.0;
  const double r = std::min(rho_at(ref_dwell_ns_), kMaxRho);
  return r < kFastRho ? 0.0 : -1.0 / std::log(r);
}

double DetectorTauEstimator::tau_ns() const noexcept { return ref_dwell_ns_ > 0 ? tau_px() * ref_dwell_ns_ : 0.0; }

}  // namespace sempose::pose
