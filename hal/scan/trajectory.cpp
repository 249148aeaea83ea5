#include "sempose/hal/trajectory.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/hal/sim_rng.hpp"

namespace sempose::hal {

namespace {
constexpr double kTwoPi = 6.283185307179586;
}

Trajectory::Trajectory(const config::TrajectoryConfig& cfg, Pose2 start, std::int32_t field_w,
                       std::int32_t field_h, std::uint64_t seed) noexcept
    : cfg_(cfg), start_(start), seed_(seed), knot_(start) {
  const std::string& k = cfg.kind;
  kind_ = k == "linear" ? Kind::kLinear
          : k == "sine" ? Kind::kSine
          : k == "steps" ? Kind::kSteps
          : k == "jumps" ? Kind::kJumps
          : k == "spin" ? Kind::kSpin
          : k == "random_walk" ? Kind::kRandomWalk
                               : Kind::kStatic;
  const double m_x = std::min(cfg.margin_px, (field_w - 1) / 2.0);
  const double m_y = std::min(cfg.margin_px, (field_h - 1) / 2.0);
  lo_x_ = m_x, hi_x_ = field_w - 1 - m_x;
  lo_y_ = m_y, hi_y_ = field_h - 1 - m_y;
  checkpoint_index_.fill(-1);
  checkpoint_[0] = start_;
  checkpoint_index_[0] = 0;
}

// Reflects x into [lo, hi] (a ball bouncing between walls).
double Trajectory::bounce(double x, double lo, double hi) noexcept {
  const double span = hi - lo;
  if (span <= 0) return lo;
  double r = std::fmod(x - lo, 2 * span);
  if (r < 0) r += 2 * span;
  return lo + (r <= span ? r : 2 * span - r);
}

Pose2 Trajectory::at(double t) noexcept {
  Pose2 p = start_;
  switch (kind_) {
    case Kind::kStatic:
      break;
    case Kind::kLinear:
      p.x_px = bounce(start_.x_px + cfg_.vx_px_s * t, lo_x_, hi_x_);
      p.y_px = bounce(start_.y_px + cfg_.vy_px_s * t, lo_y_, hi_y_);
      p.phi_deg = start_.phi_deg + cfg_.omega_deg_s * t;
      break;
    case Kind::kSine: {
      const double s = std::sin(kTwoPi * t / cfg_.period_s);
      p.x_px += cfg_.amplitude_x_px * s;
      p.y_px += cfg_.amplitude_y_px * std::sin(2.0 * kTwoPi * t / cfg_.period_s);  // a figure eight
      p.phi_deg += cfg_.amplitude_phi_deg * std::sin(kTwoPi * t / (1.7 * cfg_.period_s));
      break;
    }
    case Kind::kSteps: {
      // Staircase up `steps` steps, then back down: a triangle wave of whole steps.
      const auto k = static_cast<std::int64_t>(std::floor(t / cfg_.period_s));
      const std::int64_t n = cfg_.steps;
      std::int64_t m = k % (2 * n);
      if (m < 0) m += 2 * n;
      const double level = static_cast<double>(m <= n ? m : 2 * n - m);
      p.x_px += cfg_.amplitude_x_px * level;
      p.y_px += cfg_.amplitude_y_px * level;
      p.phi_deg += cfg_.amplitude_phi_deg * level;
      break;
    }
    case Kind::kJumps: {
      // Holds still, then jumps to a random place in the bounds every period.
      const auto k = static_cast<std::int64_t>(std::floor(t / cfg_.period_s));
      if (k <= 0) break;
      const auto uk = static_cast<std::uint64_t>(k);
      p.x_px = lo_x_ + (hi_x_ - lo_x_) * SimRng::hash_uniform(seed_, uk, 1);
      p.y_px = lo_y_ + (hi_y_ - lo_y_) * SimRng::hash_uniform(seed_, uk, 2);
      p.phi_deg += cfg_.amplitude_phi_deg * (2 * SimRng::hash_uniform(seed_, uk, 3) - 1);
      break;
    }
    case Kind::kSpin:
      p.phi_deg += cfg_.omega_deg_s * t;
      break;
    case Kind::kRandomWalk:
      p = random_walk(t);
      break;
  }
  p.phi_deg = wrap_deg(p.phi_deg);
  return p;
}

Pose2 Trajectory::walk_step(std::int64_t k, Pose2 p) const noexcept {
  const double dt = cfg_.knot_s;
  const auto uk = static_cast<std::uint64_t>(k);
  // Box–Muller from hashed uniforms: independent of call order.
  auto gauss = [&](std::uint64_t lane) {
    const double u1 = SimRng::hash_uniform(seed_, uk, lane) + 1e-300;
    const double u2 = SimRng::hash_uniform(seed_, uk, lane + 100);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
  };
  const double s = std::sqrt(dt);
  p.x_px = bounce(p.x_px + cfg_.sigma_px_per_sqrt_s * s * gauss(1), lo_x_, hi_x_);
  p.y_px = bounce(p.y_px + cfg_.sigma_px_per_sqrt_s * s * gauss(2), lo_y_, hi_y_);
  p.phi_deg = p.phi_deg + cfg_.sigma_deg_per_sqrt_s * s * gauss(3);
  return p;
}

Pose2 Trajectory::knot_at(std::int64_t k) noexcept {
  // Forward: the cursor moves on, leaving a checkpoint at every stride.
  while (k_ < k) {
    knot_ = walk_step(k_++, knot_);
    if (k_ % kCheckpointStride == 0) {
      const std::int64_t c = k_ / kCheckpointStride;
      checkpoint_[static_cast<std::size_t>(c) % kCheckpoints] = knot_;
      checkpoint_index_[static_cast<std::size_t>(c) % kCheckpoints] = c;
    }
  }
  if (k == k_) return knot_;
  // Back: from the checkpoint at or before k when it is still kept, else from the start.
  const std::int64_t c = k / kCheckpointStride;
  const std::size_t slot = static_cast<std::size_t>(c) % kCheckpoints;
  std::int64_t from = 0;
  Pose2 p = start_;
  if (checkpoint_index_[slot] == c) {
    from = c * kCheckpointStride;
    p = checkpoint_[slot];
  }
  while (from < k) p = walk_step(from++, p);
  return p;
}

Pose2 Trajectory::random_walk(double t) noexcept {
  if (t < 0) t = 0;
  const double dt = cfg_.knot_s;
  const auto k = static_cast<std::int64_t>(std::floor(t / dt));
  const Pose2 knot = knot_at(k);
  // Linear between knots k and k+1 so the motion is continuous.
  const Pose2 next = walk_step(k, knot);
  const double f = t / dt - static_cast<double>(k);
  return {knot.x_px + f * (next.x_px - knot.x_px), knot.y_px + f * (next.y_px - knot.y_px),
          knot.phi_deg + f * (next.phi_deg - knot.phi_deg)};
}

}  // namespace sempose::hal
