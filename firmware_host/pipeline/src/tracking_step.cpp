#include "sempose/pipeline/tracking_step.hpp"

#include <algorithm>

#include "sempose/pipeline/pose_input.hpp"
#include "sempose/pipeline/pose_record.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::pipeline {

TrackingStep::TrackingStep(const config::GovernorConfig& governor, const hal::ScanLimits& limits,
                           std::vector<pose::Tracker*> trackers, const StageClock& clock)
    : clock_(clock),
      limits_(limits),
      trackers_(std::move(trackers)),
      governor_(governor, limits, std::max<int>(1, static_cast<int>(trackers_.size()))) {
  // Once per pair (~0.1 s at 128²): one's turned copies already cover the other's turns.
  for (std::size_t t = 0; t < trackers_.size() && t < alike_.size(); ++t) {
    for (std::size_t u = t + 1; u < trackers_.size() && u < alike_.size(); ++u) {
      alike_[t][u] = alike_[u][t] = trackers_[t]->likeness(*trackers_[u]) >= pose::Tracker::kAlike;
    }
  }
}

TrackingStep::Outcome TrackingStep::track(hal::FrameMeta& m, const hal::Pixel* pixels) noexcept {
  Outcome o;
  o.target = m.target < trackers_.size() ? m.target : 0;
  o.prev_pose_done_ns = prev_pose_done_ns_;
  o.t_start_ns = clock_.pose_start_ns(m.t_seen_ns, prev_pose_done_ns_);
  const std::int64_t wall0 = rt::now_ns();
  pose::PoseFrame frame = to_pose_frame(m, pixels);
  frame.held_by_others = held_by_others(o.target);
  o.est = trackers_[o.target]->update(frame);
  // The target's first frame after this step asked it to search again runs that search (a
  // full-field frame: its pose is the search's; an ROI frame: ACQUIRING with reason 32) unless
  // the frame was bad, which leaves the request for the next one.
  if (own_reacquire_[o.target] && (o.est.reason_bits & pose::kReasonBadFrame) == 0) {
    o.est.look_alike = true;
    own_reacquire_[o.target] = false;
  }
  const std::int64_t t_mid_ns = m.t_scan_start_ns / 2 + m.t_scan_end_ns / 2;
  if (on_a_look_alikes_place(o.target, o.est, t_mid_ns)) {
    if (o.est.state == pose::TrackState::kTracking) o.est.state = pose::TrackState::kUncertain;
    o.est.look_alike = true;
    if (++same_place_frames_[o.target] >= kSamePlaceFrames) {
      trackers_[o.target]->request_reacquire(/*commanded=*/false);
      own_reacquire_[o.target] = true;
      same_place_frames_[o.target] = 0;
    }
  } else {
    same_place_frames_[o.target] = 0;
  }
  // A target holds its object while it is followed (TRACKING, or UNCERTAIN at a pose its
  // tracker follows: a first start's search frame waiting to be confirmed, a doubted ROI frame).
  Held& h = held_[o.target];
  const bool followed = o.est.followed;
  const double dt = static_cast<double>(t_mid_ns - h.t_ns);
  const bool moving = followed && h.held && dt > 0;
  h = {followed, o.est.x_px, o.est.y_px, t_mid_ns, moving ? (o.est.x_px - h.x_px) / dt : 0.0,
       moving ? (o.est.y_px - h.y_px) / dt : 0.0};
  const std::int64_t wall1 = rt::now_ns();
  o.compute_ns = clock_.compute_ns(wall1 - wall0);
  m.t_pose_done_ns = clock_.pose_done_ns(o.t_start_ns, o.compute_ns, wall1);
  prev_pose_done_ns_ = m.t_pose_done_ns;
  const bool tracking = o.est.state == pose::TrackState::kTracking;
  governor_.observe(o.target, o.compute_ns, o.est.score, o.est.psr, tracking && !o.est.searched);
  governor_.set_dwell_floor(o.target, trackers_[o.target]->shortest_correctable_dwell_ns());
  // A bad frame is the source's fault, not the dwell's.
  if (o.est.state == pose::TrackState::kLost && !o.est.searched && (o.est.reason_bits & pose::kReasonBadFrame) == 0)
    governor_.lost_on_roi(o.target);
  return o;
}

bool TrackingStep::on_a_look_alikes_place(std::uint8_t target, const pose::PoseEstimate& est,
                                          std::int64_t t_ns) const noexcept {
  if (!est.followed) return false;
  for (std::size_t t = 0; t < trackers_.size() && t < held_.size(); ++t) {
    if (t == target || !alike_[target][t] || !held_[t].held) continue;
    // The other's place carried to this frame's time at its last velocity.
    const double ahead = static_cast<double>(t_ns - held_[t].t_ns);
    const double dx = est.x_px - (held_[t].x_px + held_[t].vx_px_ns * ahead);
    const double dy = est.y_px - (held_[t].y_px + held_[t].vy_px_ns * ahead);
    if (dx * dx + dy * dy < kSamePlacePx * kSamePlacePx) return true;
  }
  return false;
}

pose::HeldPlaces TrackingStep::held_by_others(std::uint8_t target) const noexcept {
  pose::HeldPlaces h;
  for (std::size_t t = 0; t < trackers_.size() && t < held_.size(); ++t) {
    if (!alike_[target][t] || !held_[t].held || h.count >= pose::kMaxHeldPlaces) continue;
    h.x_px[h.count] = held_[t].x_px;
    h.y_px[h.count] = held_[t].y_px;
    ++h.count;
  }
  return h;
}

hal::ScanRequest TrackingStep::next_scan(std::uint8_t target) noexcept {
  hal::ScanRequest req;
  req.roi = trackers_[target]->next_roi();
  req.target = target;
  req.dwell_ns = governor_.dwell_for_scan(target, req.roi.w, req.roi.h,
                                          limits_.is_full_field(req.roi.x, req.roi.y, req.roi.w, req.roi.h));
  return req;
}

PoseRecord TrackingStep::record(const hal::FrameMeta& m, const Outcome& o, double nm_per_px) noexcept {
  return make_pose_record(m, o.est, o.target, pose_seq_[o.target]++, nm_per_px);
}

}  // namespace sempose::pipeline
