#include "sempose/pose/pose_filter.hpp"

#include "sempose/rt/angle.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace sempose::pose {
namespace {

using Vec3 = std::array<double, 3>;
using Mat3 = std::array<Vec3, 3>;

// The jerk setting is "1σ of a jerk held over one 10 ms frame"; the continuous white-jerk
// density that injects the same acceleration variance per 10 ms is q = jerk² · 10 ms. The
// continuous form is what makes Q exact for any (varying) frame interval.
constexpr double kJerkReferenceInterval_s = 0.01;
// After a (re)start velocity and acceleration are unknown: variances far above any motion a
// ROI tracker can follow, so the next two measurements alone determine them (the first
// outputs after a restart are the raw measurements, never a coasted guess).
constexpr double kInitialVelocityVar = 1e4 * 1e4;      // (units/s)²
constexpr double kInitialAccelerationVar = 1e6 * 1e6;  // (units/s²)²

constexpr int kAxisX = 0, kAxisY = 1, kAxisPhi = 2;

// Process-noise adaptation (adapt_jerk). A consistent filter has E[y²/S] = 1; averaged over
// ~10 frames (α = 0.1, spread ≈ 0.3) a value above 2 is lag, not noise. Raising by 1.5 per
// frame catches up within a few frames; 0.98 per frame decays over ~35 frames (a 1 s sine
// swing is caught in its fast part and released in its slow one). Limit: jerk ×100.
constexpr double kNisAverageWeight = 0.1;
constexpr double kNisInconsistent = 2.0;
constexpr double kNoiseRaisePerFrame = 1.5;
constexpr double kNoiseDecayPerFrame = 0.98;
constexpr double kMaxNoiseScale = 1e4;


bool finite(const PoseSample& s) noexcept {
  return std::isfinite(s.t_s) && std::isfinite(s.x_px) && std::isfinite(s.y_px) && std::isfinite(s.phi_deg);
}

// x ← F x, P ← F P Fᵀ + Q(dt) for the constant-acceleration model with white jerk of density q.
void predict(PoseFilter::AxisState& a, double dt, double q) noexcept {
  const double dt2 = dt * dt, dt3 = dt2 * dt, dt4 = dt3 * dt, dt5 = dt4 * dt;
  const Mat3 F{{{1.0, dt, 0.5 * dt2}, {0.0, 1.0, dt}, {0.0, 0.0, 1.0}}};
  const Mat3 Q{{{dt5 / 20.0, dt4 / 8.0, dt3 / 6.0}, {dt4 / 8.0, dt3 / 3.0, dt2 / 2.0}, {dt3 / 6.0, dt2 / 2.0, dt}}};
  Vec3 x{};
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) x[i] += F[i][k] * a.x[k];
  Mat3 FP{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) FP[i][j] += F[i][k] * a.P[k][j];
  Mat3 P{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0.0;
      for (int k = 0; k < 3; ++k) s += FP[i][k] * F[j][k];
      P[i][j] = s + q * Q[i][j];
    }
  a.x = x;
  a.P = P;
}

// Measurement of the position only (H = [1 0 0]); Joseph form keeps P symmetric positive.
void correct(PoseFilter::AxisState& a, double innovation, double r2) noexcept {
  const double S = a.P[0][0] + r2;
  const Vec3 K{a.P[0][0] / S, a.P[1][0] / S, a.P[2][0] / S};
  for (int i = 0; i < 3; ++i) a.x[i] += K[i] * innovation;
  // (I - K H) P (I - K H)ᵀ + K r² Kᵀ, with (I - K H) P = P - K P[0][·].
  Mat3 A{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) A[i][j] = a.P[i][j] - K[i] * a.P[0][j];
  Mat3 P{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) P[i][j] = A[i][j] - A[i][0] * K[j] + K[i] * r2 * K[j];
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j) P[i][j] = P[j][i] = 0.5 * (P[i][j] + P[j][i]);
  a.P = P;
}

void check_positive(double v, const char* name, double lo) {
  if (!(v >= lo) || !std::isfinite(v))
    throw std::invalid_argument(std::string("PoseFilterConfig.") + name + ": " + std::to_string(v) +
                                " is not finite and >= " + std::to_string(lo));
}

}  // namespace

const char* to_string(PoseFilterEvent event) noexcept {
  switch (event) {
    case PoseFilterEvent::kDisabled: return "disabled";
    case PoseFilterEvent::kStarted: return "started";
    case PoseFilterEvent::kFiltered: return "filtered";
    case PoseFilterEvent::kGateReset: return "gate_reset";
    case PoseFilterEvent::kGapReset: return "gap_reset";
    case PoseFilterEvent::kInvalidInput: return "invalid_input";
  }
  return "unknown";
}

PoseFilter::PoseFilter(const config::PoseFilterConfig& config) : config_(config) {
  // Same lower bounds as the YAML reader (config/src/pose_filter_section.cpp).
  check_positive(config.meas_sigma_px, "meas_sigma_px", 1e-4);
  check_positive(config.meas_sigma_deg, "meas_sigma_deg", 1e-4);
  check_positive(config.jerk_px_s3, "jerk_px_s3", 1e-3);
  check_positive(config.jerk_deg_s3, "jerk_deg_s3", 1e-3);
  check_positive(config.gate_sigma, "gate_sigma", 1.0);
  check_positive(config.max_gap_s, "max_gap_s", 1e-4);
  meas_var_ = {config.meas_sigma_px * config.meas_sigma_px, config.meas_sigma_px * config.meas_sigma_px,
               config.meas_sigma_deg * config.meas_sigma_deg};
  jerk_psd_ = {config.jerk_px_s3 * config.jerk_px_s3 * kJerkReferenceInterval_s,
               config.jerk_px_s3 * config.jerk_px_s3 * kJerkReferenceInterval_s,
               config.jerk_deg_s3 * config.jerk_deg_s3 * kJerkReferenceInterval_s};
  reset();
}

void PoseFilter::reset() noexcept {
  started_ = false;
  last_t_s_ = 0.0;
  for (auto& a : axes_) a = AxisState{};
  noise_scale_ = {1.0, 1.0, 1.0};
  nis_average_ = {1.0, 1.0, 1.0};
}

PoseSample PoseFilter::start_from(const PoseSample& m, PoseFilterEvent event) noexcept {
  PoseSample out = m;
  out.phi_deg = rt::wrap_deg(m.phi_deg);
  const Vec3 z{out.x_px, out.y_px, out.phi_deg};
  for (int i = 0; i < 3; ++i) {
    AxisState& a = axes_[static_cast<std::size_t>(i)];
    a = AxisState{};
    a.x[0] = z[static_cast<std::size_t>(i)];
    a.P[0][0] = meas_var_[static_cast<std::size_t>(i)];
    a.P[1][1] = kInitialVelocityVar;
    a.P[2][2] = kInitialAccelerationVar;
  }
  nis_average_ = {1.0, 1.0, 1.0};  // the learnt noise_scale_ stays: the motion is still as fast
  last_t_s_ = m.t_s;
  started_ = true;
  last_event_ = event;
  return out;
}

PoseSample PoseFilter::update(const PoseSample& m) noexcept {
  if (!config_.enabled) {
    last_event_ = PoseFilterEvent::kDisabled;
    return m;
  }
  if (!finite(m)) {
    // Not ours to invent a pose: the caller's bad value comes back as it is (the tracker
    // never emits one), and the filter starts afresh on the next good pose.
    reset();
    last_event_ = PoseFilterEvent::kInvalidInput;
    return m;
  }
  if (!started_) return start_from(m, PoseFilterEvent::kStarted);
  const double dt = m.t_s - last_t_s_;
  if (!(dt > 0.0) || dt > config_.max_gap_s) return start_from(m, PoseFilterEvent::kGapReset);

  for (std::size_t i = 0; i < 3; ++i) predict(axes_[i], dt, jerk_psd_[i] * noise_scale_[i]);
  axes_[kAxisPhi].x[0] = rt::wrap_deg(axes_[kAxisPhi].x[0]);

  // Innovations of all three axes first: one broken axis re-initialises the whole pose (a
  // jump or a torn frame spoils x, y and φ together).
  const Vec3 z{m.x_px, m.y_px, m.phi_deg};
  Vec3 innovation{};
  Vec3 nis{};  // normalized innovation squared, y²/S
  for (std::size_t i = 0; i < 3; ++i) {
    const AxisState& a = axes_[i];
    innovation[i] = z[i] - a.x[0];
    if (i == kAxisPhi) innovation[i] = rt::wrap_deg(innovation[i]);
    const double S = a.P[0][0] + meas_var_[i];
    nis[i] = innovation[i] * innovation[i] / S;
    if (nis[i] > config_.gate_sigma * config_.gate_sigma) return start_from(m, PoseFilterEvent::kGateReset);
  }
  for (std::size_t i = 0; i < 3; ++i) {
    correct(axes_[i], innovation[i], meas_var_[i]);
    if (!config_.adapt_jerk) continue;
    nis_average_[i] += kNisAverageWeight * (nis[i] - nis_average_[i]);
    noise_scale_[i] = nis_average_[i] > kNisInconsistent
                          ? std::min(kMaxNoiseScale, noise_scale_[i] * kNoiseRaisePerFrame)
                          : std::max(1.0, noise_scale_[i] * kNoiseDecayPerFrame);
  }
  axes_[kAxisPhi].x[0] = rt::wrap_deg(axes_[kAxisPhi].x[0]);

  const PoseSample out{m.t_s, axes_[kAxisX].x[0], axes_[kAxisY].x[0], axes_[kAxisPhi].x[0]};
  // Cannot happen with finite input and a bounded dt; if arithmetic ever overflows, the
  // measurement is still a valid pose.
  if (!finite(out)) return start_from(m, PoseFilterEvent::kGapReset);
  last_t_s_ = m.t_s;
  last_event_ = PoseFilterEvent::kFiltered;
  return out;
}

}  // namespace sempose::pose
