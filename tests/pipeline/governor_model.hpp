// A deterministic virtual-time model of the pipeline's timing around the governor, with
// the pipeline's policies: acquisition starts scan k+1 the moment scan k ends, with the dwell
// the correlation published last for that target; the correlation, when free, takes the
// NEWEST finished frame (older waiting ones are dropped, as the real stage drains its ring),
// computes for compute_ns(k) and publishes that target's next dwell when done. An overrun is
// a processed frame that had to wait for the correlation (its scan ended while it was busy).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "sempose/pipeline/scan_speed_governor.hpp"

namespace sempose::pipeline::test {

struct ModelStep {
  int frame = 0;
  std::int64_t t_scan_start_ns = 0;
  std::int64_t t_scan_end_ns = 0;
  std::int64_t t_pose_done_ns = 0;  // 0 when dropped
  std::int64_t compute_ns = 0;
  std::uint32_t dwell_ns = 0;
  bool overrun = false;
  bool dropped = false;
};

struct ModelParams {
  std::int32_t roi_w = 128;
  std::int32_t roi_h = 128;
  int targets = 1;
};

// compute_ns(k) and score(k) script the run.
inline std::vector<ModelStep> run_model(ScanSpeedGovernor& gov, const hal::ScanLimits& limits,
                                        const ModelParams& p, int frames,
                                        const std::function<std::int64_t(int)>& compute_ns,
                                        const std::function<float(int)>& score = nullptr) {
  std::vector<ModelStep> out;
  out.reserve(static_cast<std::size_t>(frames));
  // Published dwell per target, with the time it became visible to acquisition.
  struct Pub { std::int64_t t_ns; std::uint32_t dwell_ns; };
  std::vector<std::vector<Pub>> published(static_cast<std::size_t>(p.targets));
  for (int t = 0; t < p.targets; ++t) {
    published[static_cast<std::size_t>(t)].push_back(
        {0, gov.next_dwell_ns(static_cast<std::uint8_t>(t), p.roi_w, p.roi_h)});
  }
  auto dwell_at = [&](int target, std::int64_t t_ns) {
    std::uint32_t d = 0;
    for (const auto& pub : published[static_cast<std::size_t>(target)]) {
      if (pub.t_ns <= t_ns) d = pub.dwell_ns;
    }
    return d;
  };
  std::int64_t t_free = 0;      // correlation busy until
  std::size_t next_unprocessed = 0;
  // Lets the correlation make every decision due at or before `horizon_ns`.
  auto correlate_until = [&](std::int64_t horizon_ns) {
    while (next_unprocessed < out.size()) {
      const std::int64_t t_decide = std::max(t_free, out[next_unprocessed].t_scan_end_ns);
      if (t_decide > horizon_ns) return;
      std::size_t j = next_unprocessed;  // newest frame finished by t_decide
      while (j + 1 < out.size() && out[j + 1].t_scan_end_ns <= t_decide) ++j;
      for (std::size_t d = next_unprocessed; d < j; ++d) out[d].dropped = true;
      ModelStep& s = out[j];
      s.overrun = t_decide > s.t_scan_end_ns;
      s.compute_ns = compute_ns(s.frame);
      s.t_pose_done_ns = t_decide + s.compute_ns;
      t_free = s.t_pose_done_ns;
      const int target = s.frame % p.targets;
      gov.observe(static_cast<std::uint8_t>(target), s.compute_ns, score ? score(s.frame) : 0.9f, 10.0f, true);
      published[static_cast<std::size_t>(target)].push_back(
          {s.t_pose_done_ns, gov.next_dwell_ns(static_cast<std::uint8_t>(target), p.roi_w, p.roi_h)});
      next_unprocessed = j + 1;
    }
  };
  std::int64_t t_scan = 0;
  for (int k = 0; k < frames; ++k) {
    correlate_until(t_scan);
    ModelStep s;
    s.frame = k;
    s.dwell_ns = dwell_at(k % p.targets, t_scan);
    s.t_scan_start_ns = t_scan;
    s.t_scan_end_ns = t_scan + limits.scan_time_ns(p.roi_w, p.roi_h, s.dwell_ns);
    t_scan = s.t_scan_end_ns;
    out.push_back(s);
  }
  correlate_until(INT64_MAX);
  return out;
}

}  // namespace sempose::pipeline::test
