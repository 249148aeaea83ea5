// x(t), y(t), φ(t) of a simulated target (t in seconds since the source started), in the
// the README's conventions. Pure function of t and the seed, except random_walk, which keeps
// a cursor so that monotone time costs O(1) per call, and a checkpoint every 256 knots (the
// last 64) so that going back a little, as every frame does (its lines rise to the scan's end,
// then the truth is asked at mid-scan), costs at most 256 steps. It replayed from t = 0 on every
// frame: O(frames²) recordings, and a run's acquisition slower by ~5 ms a frame after an hour.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "sempose/config/sim_config.hpp"
#include "sempose/rt/angle.hpp"

namespace sempose::hal {

struct Pose2 {
  double x_px = 0, y_px = 0, phi_deg = 0;
};

class Trajectory {
 public:
  Trajectory() = default;
  // field_w/h and cfg.margin_px give the bounds for bouncing, jumps and the random walk.
  Trajectory(const config::TrajectoryConfig& cfg, Pose2 start, std::int32_t field_w, std::int32_t field_h,
             std::uint64_t seed) noexcept;
  Pose2 at(double t_s) noexcept;

 private:
  enum class Kind : std::uint8_t { kStatic, kLinear, kSine, kSteps, kJumps, kSpin, kRandomWalk };
  Pose2 random_walk(double t_s) noexcept;
  Pose2 walk_step(std::int64_t k, Pose2 p) const noexcept;  // knot k+1 from knot k
  Pose2 knot_at(std::int64_t k) noexcept;                   // knot k (cursor, checkpoint or replay)
  static double bounce(double x, double lo, double hi) noexcept;

  config::TrajectoryConfig cfg_{};
  Kind kind_ = Kind::kStatic;
  Pose2 start_{};
  double lo_x_ = 0, hi_x_ = 0, lo_y_ = 0, hi_y_ = 0;
  std::uint64_t seed_ = 0;
  // random walk cursor: pose at knot k_
  std::int64_t k_ = 0;
  Pose2 knot_{};
  static constexpr std::int64_t kCheckpointStride = 256;
  static constexpr std::size_t kCheckpoints = 64;
  std::array<Pose2, kCheckpoints> checkpoint_{};  // knot c·stride at [c % kCheckpoints]
  std::array<std::int64_t, kCheckpoints> checkpoint_index_{};  // its c (-1: empty)
};

// Wraps degrees into (-180, 180] (the one wrap, shared with the pose engine).
using rt::wrap_deg;

}  // namespace sempose::hal
