#include "sempose/pose/loss_policy.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/track_state.hpp"

namespace sempose::pose {

bool LossPolicy::below_recent(const Measurement& m) const noexcept {
  return cfg_.relative_score_threshold > 0 && have_score_mean_ && m.score < cfg_.relative_score_threshold * score_mean_;
}

bool LossPolicy::unexplained(const Measurement& m) const noexcept {
  if (calibrating_ || cfg_.explained_threshold <= 0 || !(m.attainable > 0)) return false;
  if (m.score < cfg_.explained_threshold * m.attainable) return true;
  // A held target comes back only when the pattern explains it: its level may be a deformed one.
  return m.score < explained_bound() * m.attainable && (held_ || !at_own_level(m.score));
}

bool LossPolicy::at_own_level(float score) const noexcept {
  if (!have_peak_) return true;  // nothing known of the target yet: the plain threshold decides
  // Only the room a ZNCC of that level has, not the running spread: a deforming target's
  // scores spread widely, which would excuse the very frames this is about.
  return score >= peak_ - kLevelShare * (1.0 - peak_ * peak_);
}

bool LossPolicy::only_unexplained(const Measurement& m) const noexcept {
  return weak_reasons(m) == kReasonUnexplained && !m.implausible && m.score > roi_floor_ && m.score >= cfg_.score_threshold;
}

bool LossPolicy::weak(const Measurement& m) const noexcept {
  return !m.valid || m.score < cfg_.score_threshold || m.score <= roi_floor_ || below_recent(m) ||
         (cfg_.psr_threshold > 0 && m.psr_valid && m.psr < cfg_.psr_threshold) || unexplained(m) || m.implausible;
}

std::uint8_t LossPolicy::weak_reasons(const Measurement& m) const noexcept {
  std::uint8_t b = 0;
  if (!m.valid || m.score < cfg_.score_threshold || m.score <= roi_floor_ || below_recent(m)) b |= kReasonLowScore;
  if (cfg_.psr_threshold > 0 && m.psr_valid && m.psr < cfg_.psr_threshold) b |= kReasonLowPsr;
  if (unexplained(m) || m.implausible) b |= kReasonUnexplained;
  return b;
}

bool LossPolicy::found(const Measurement& m, double attainable) const noexcept {
  if (!m.valid || weak(m) || m.score <= field_floor_) return false;
  if (calibrating_ || cfg_.relative_score_threshold <= 0) return true;
  if (m.score < cfg_.relative_score_threshold * attainable) return false;
  return !have_ref_ || m.score >= cfg_.relative_score_threshold * ref_score_;
}

FrameVerdict LossPolicy::judge(const Measurement& m) noexcept {
  if (!weak(m)) return FrameVerdict::kAccept;
  return ++weak_frames_ >= cfg_.lost_after_frames ? FrameVerdict::kLost : FrameVerdict::kCoast;
}

double LossPolicy::confirm_margin() const noexcept {
  if (!have_score_mean_) return 0.0;
  return std::max(kConfirmSigmas * std::sqrt(score_var_), kConfirmShare * (1.0 - score_mean_ * score_mean_));
}

bool LossPolicy::confirmed(float score) const noexcept {
  return have_score_mean_ && score >= score_mean_ - confirm_margin();
}

double LossPolicy::false_probability(double sigma_px, double sigma_deg) noexcept {
  const double p_pos = sigma_px > 0 ? std::exp(-kFalsePx * kFalsePx / (2.0 * sigma_px * sigma_px)) : 0.0;
  const double p_phi = sigma_deg > 0 ? std::erfc(kFalseDeg / (sigma_deg * std::sqrt(2.0))) : 0.0;
  return std::max(p_pos, p_phi);
}

namespace {
// e^−x·I0(x), the modified Bessel function scaled so that it stays finite: the power series
// below 15, the asymptotic expansion above (relative error < 1e-5 there).
double bessel_i0_scaled(double x) noexcept {
  x = std::fabs(x);
  if (x < 15.0) {
    double term = 1.0, sum = 1.0;
    const double q = 0.25 * x * x;
    for (int k = 1; k < 60 && term > 1e-17 * sum; ++k) {
      term *= q / (static_cast<double>(k) * k);
      sum += term;
    }
    return sum * std::exp(-x);
  }
  const double t = 1.0 / (8.0 * x);
  return (1.0 + t * (1.0 + 4.5 * t * (1.0 + 25.0 / 6.0 * t))) / std::sqrt(2.0 * M_PI * x);
}
}  // namespace

double LossPolicy::false_probability_offset(double offset_px, double sd_px, double offset_deg, double sd_deg) noexcept {
  double p_pos = 0.0;
  if (sd_px > 0) {
    // P(|e| > R) = 1 − ∫0^R r/s² · exp(−(r − m)²/2s²) · e^−(rm/s²) I0(rm/s²) dr (Simpson, 96 steps).
    const double s2 = sd_px * sd_px, m = offset_px, big_r = kFalsePx;
    constexpr int kSteps = 96;
    const double h = big_r / kSteps;
    double inside = 0.0;
    for (int i = 0; i <= kSteps; ++i) {
      const double r = i * h;
      const double f = r / s2 * std::exp(-(r - m) * (r - m) / (2.0 * s2)) * bessel_i0_scaled(r * m / s2);
      inside += f * (i == 0 || i == kSteps ? 1.0 : (i % 2 ? 4.0 : 2.0));
    }
    p_pos = std::clamp(1.0 - inside * h / 3.0, 0.0, 1.0);
  }
  double p_phi = 0.0;
  if (sd_deg > 0) {
    const double k = 1.0 / (sd_deg * std::sqrt(2.0));
    p_phi = 0.5 * std::erfc((kFalseDeg - offset_deg) * k) + 0.5 * std::erfc((kFalseDeg + offset_deg) * k);
  }
  return std::max(p_pos, p_phi);
}

bool LossPolicy::trusted_offset(double offset_px, double sd_px, double offset_deg, double sd_deg) const noexcept {
  if (calibrating_ || !(cfg_.max_false_probability > 0)) return true;
  // |e| > R needs |e − mean| > R − offset: that Rayleigh tail bounds the Rice tail from above, so
  // most frames are settled without the quadrature (97 Bessel terms, a few µs).
  const double room_px = kFalsePx - offset_px;
  const double bound_px = sd_px > 0 ? (room_px > 0 ? std::exp(-room_px * room_px / (2.0 * sd_px * sd_px)) : 1.0) : 0.0;
  const double p_phi = sd_deg > 0 ? 0.5 * std::erfc((kFalseDeg - offset_deg) / (sd_deg * std::sqrt(2.0))) +
                                        0.5 * std::erfc((kFalseDeg + offset_deg) / (sd_deg * std::sqrt(2.0)))
                                  : 0.0;
  if (std::max(bound_px, p_phi) <= cfg_.max_false_probability) return true;
  return false_probability_offset(offset_px, sd_px, offset_deg, sd_deg) <= cfg_.max_false_probability;
}

bool LossPolicy::trusted(double sigma_px, double sigma_deg) const noexcept {
  if (calibrating_ || !(cfg_.max_false_probability > 0)) return true;
  return false_probability(sigma_px, sigma_deg) <= cfg_.max_false_probability;
}

void LossPolicy::accepted(float score) noexcept {
  if (have_score_mean_ && !calibrating_) {
    const double d = score - score_mean_;
    score_var_ = have_score_var_ ? 0.8 * score_var_ + 0.2 * d * d : d * d;
    have_score_var_ = true;
  }
  score_mean_ = have_score_mean_ ? 0.8 * score_mean_ + 0.2 * score : score;
  if (!calibrating_) {
    // Of the running mean, not of single scores: the highest of noisy scores sits well above
    // the level a target keeps (at 2.5 e⁻/px by ~2 SD), which would make its ordinary frames
    // look like a decline.
    peak_ = have_peak_ ? std::max(score_mean_, 0.97 * peak_ + 0.03 * score_mean_) : score_mean_;
    have_peak_ = true;
  }
  have_score_mean_ = true;
  weak_frames_ = 0;
  ref_score_ = score_mean_;
  have_ref_ = !calibrating_;
}

void LossPolicy::reset() noexcept {
  have_score_mean_ = false;
  weak_frames_ = 0;
  // Found again after a loss, the target sits on other background (a jump) and scores at a
  // level of its own there; a held target keeps its level (judge_reset() only).
  have_peak_ = false;
}

}  // namespace sempose::pose
