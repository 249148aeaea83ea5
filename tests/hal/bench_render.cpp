// Render time of the simulated SEM against the ROI's own scan time at 250 ns dwell: the
// simulator must be much faster than the scan it imitates (real-clock mode renders in start()
// and then waits for the scan end). Default scene: the real needle texture plus the noise model.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

#include <time.h>

#include "sempose/hal/sim_source.hpp"

using namespace sempose;

// CPU time of this thread: the render's own cost, not the other processes sharing the cores.
static double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int main() {
  hal::ScanLimits lim;
  config::SimConfig cfg;
  cfg.clock = "virtual";
  cfg.targets[0].texture.path = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";
  cfg.targets[1].enabled = true;  // both targets: the worst case of the default scene
  hal::SimSource src(lim, cfg);
  int failures = 0;
  for (int size : {128, 192, 256}) {
    std::vector<hal::Pixel> px(static_cast<std::size_t>(size) * size);
    hal::TargetTruth truth[hal::kMaxTargets];
    std::vector<double> ms, cpu;
    const int x0 = 512 - size / 2, y0 = 384 - size / 2;  // over the needle
    for (int i = 0; i < 200; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = cpu_ms();
      src.render({x0, y0, size, size}, 250, hal::SimSource::kVirtualEpochNs + i * 5'000'000LL,
                 static_cast<std::uint64_t>(i), px.data(), truth);
      cpu.push_back(cpu_ms() - c0);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(ms.begin(), ms.end());
    std::sort(cpu.begin(), cpu.end());
    const double scan_ms = lim.scan_time_ns(size, size, 250) * 1e-6;
    std::printf("render_%d: %.3f ms = %.3f x scan time (%.2f ms at 250 ns)  [CPU median; wall median %.3f ms, p99 %.3f ms]\n",
                size, cpu[cpu.size() / 2], cpu[cpu.size() / 2] / scan_ms, scan_ms, ms[ms.size() / 2],
                ms[ms.size() * 99 / 100]);
    const auto [lo, hi] = std::minmax_element(px.begin(), px.end());
    if (*lo == *hi) {
      std::printf("render_%d: flat image: the scene did not render\n", size);
      ++failures;
    }
  }
  // Full field (what `sempose sim` records per frame).
  std::vector<hal::Pixel> full(static_cast<std::size_t>(lim.field_w) * lim.field_h);
  hal::TargetTruth truth[hal::kMaxTargets];
  const double c0 = cpu_ms();
  for (int i = 0; i < 5; ++i) src.render({0, 0, lim.field_w, lim.field_h}, 250, hal::SimSource::kVirtualEpochNs, i, full.data(), truth);
  const double ms = (cpu_ms() - c0) / 5;
  const double scan_ms = lim.scan_time_ns(lim.field_w, lim.field_h, 250) * 1e-6;
  std::printf("render_full_%dx%d: %.2f ms = %.3f x scan time (%.1f ms)\n", lim.field_w, lim.field_h, ms, ms / scan_ms, scan_ms);
  return failures == 0 ? 0 : 1;
}
