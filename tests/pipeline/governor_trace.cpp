// Scripted governor run for the README figure: the pipeline's virtual-time model
// (governor_model.hpp) with the real ScanSpeedGovernor and a compute cost that steps as it
// would in practice — more orientation steps during a spin, a second pattern set, then back —
// plus a stretch of poor match quality. The compute costs are scripted, not measured: the
// real tracker needs ~0.5 ms per pose, which keeps a 192² ROI at the minimum dwell. Prints how fast the dwell
// settles after each step and, with an output path, writes the trace as CSV for
// ci/plot-governor.
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "governor_model.hpp"

namespace {

using sempose::pipeline::ScanSpeedGovernor;

constexpr int kFrames = 400;
// (first frame, compute per pose in ns, match score, label)
struct Phase {
  int from;
  std::int64_t compute_ns;
  float score;
  const char* what;
};
constexpr Phase kPhases[] = {
    {0, 1'200'000, 0.9f, "3 angles per pose"},
    {80, 2'600'000, 0.9f, "spin: 7 angle steps per pose"},
    {160, 2'600'000, 0.35f, "poor match (charging)"},
    {200, 2'600'000, 0.9f, "match recovered"},
    {260, 4'000'000, 0.9f, "2 pattern sets per pose"},
    {330, 1'200'000, 0.9f, "back to 3 angles per pose"},
};

std::int64_t compute_at(int k) {
  std::int64_t c = kPhases[0].compute_ns;
  for (const auto& p : kPhases) {
    if (k >= p.from) c = p.compute_ns;
  }
  // ±4 % deterministic jitter, as a loaded core shows.
  return static_cast<std::int64_t>(static_cast<double>(c) * (1.0 + 0.04 * std::sin(k * 1.7)));
}

float score_at(int k) {
  float score = kPhases[0].score;
  for (const auto& p : kPhases) {
    if (k >= p.from) score = p.score;
  }
  return score;
}

}  // namespace

int main(int argc, char** argv) {
  sempose::config::GovernorConfig cfg;
  sempose::hal::ScanLimits limits;
  limits.min_dwell_ns = 100;
  limits.max_dwell_ns = 10'000;
  limits.dwell_step_ns = 50;
  limits.line_flyback_ns = 2'000;
  ScanSpeedGovernor gov(cfg, limits, 1);
  const auto steps = sempose::pipeline::test::run_model(gov, limits, {128, 128, 1}, kFrames,
                                                        compute_at, score_at);

  std::FILE* csv = argc > 1 ? std::fopen(argv[1], "w") : nullptr;
  if (argc > 1 && csv == nullptr) {
    std::fprintf(stderr, "governor_trace: cannot write %s\n", argv[1]);
    return 2;
  }
  if (csv) std::fprintf(csv, "frame,t_ms,compute_us,dwell_ns,scan_us,pose_rate_hz,overrun,dropped\n");
  int overruns = 0, dropped = 0;
  std::int64_t last_done = 0;
  for (const auto& s : steps) {
    overruns += s.overrun;
    dropped += s.dropped;
    double rate = 0;
    if (!s.dropped && last_done > 0 && s.t_pose_done_ns > last_done) {
      rate = 1e9 / static_cast<double>(s.t_pose_done_ns - last_done);
    }
    if (!s.dropped) last_done = s.t_pose_done_ns;
    if (csv) {
      std::fprintf(csv, "%d,%.3f,%.1f,%u,%.1f,%.1f,%d,%d\n", s.frame, s.t_scan_start_ns / 1e6,
                   s.compute_ns / 1e3, s.dwell_ns, (s.t_scan_end_ns - s.t_scan_start_ns) / 1e3, rate,
                   s.overrun ? 1 : 0, s.dropped ? 1 : 0);
    }
  }
  if (csv) std::fclose(csv);

  // Settling: frames after each step until the dwell stays constant for the rest of the phase.
  std::printf("governor scripted run: %d frames, 128x128 ROI, margin %.2f\n", kFrames, cfg.margin);
  for (std::size_t i = 0; i < std::size(kPhases); ++i) {
    const int from = kPhases[i].from;
    const int to = i + 1 < std::size(kPhases) ? kPhases[i + 1].from : kFrames;
    int settled = to - from;
    for (int k = to - 1; k > from && steps[k].dwell_ns == steps[k - 1].dwell_ns; --k) settled = k - 1 - from;
    std::printf("  frames %3d-%3d  %-30s compute %5.2f ms  score %.2f  dwell %5u ns  settled after %2d frames\n",
                from, to - 1, kPhases[i].what, kPhases[i].compute_ns / 1e6, kPhases[i].score, steps[to - 1].dwell_ns, settled);
  }
  std::printf("  overruns %d, dropped %d (of %d frames)\n", overruns, dropped, kFrames);
  return 0;
}
