#include "sempose/pose/loss_policy.hpp"

#include "sempose/pose/track_state.hpp"

namespace sempose::pose {

bool LossPolicy::below_recent(const Measurement& m) const noexcept {
  return cfg_.relative_score_threshold > 0 && have_score_mean_ && m.score < cfg_.relative_score_threshold * score_mean_;
}

bool LossPolicy::weak(const Measurement& m) const noexcept {
  return !m.valid || m.score < cfg_.score_threshold || below_recent(m) ||
         (cfg_.psr_threshold > 0 && m.psr_valid && m.psr < cfg_.psr_threshold);
}

std::uint8_t LossPolicy::weak_reasons(const Measurement& m) const noexcept {
  std::uint8_t b = 0;
  if (!m.valid || m.score < cfg_.score_threshold || below_recent(m)) b |= kReasonLowScore;
  if (cfg_.psr_threshold > 0 && m.psr_valid && m.psr < cfg_.psr_threshold) b |= kReasonLowPsr;
  return b;
}

FrameVerdict LossPolicy::judge(const Measurement& m) noexcept {
  if (!weak(m)) return FrameVerdict::kAccept;
  return ++weak_frames_ >= cfg_.lost_after_frames ? FrameVerdict::kLost : FrameVerdict::kCoast;
}

void LossPolicy::accepted(float score) noexcept {
  score_mean_ = have_score_mean_ ? 0.8 * score_mean_ + 0.2 * score : score;
  have_score_mean_ = true;
  weak_frames_ = 0;
}

void LossPolicy::reset() noexcept {
  have_score_mean_ = false;
  weak_frames_ = 0;
}

}  // namespace sempose::pose
