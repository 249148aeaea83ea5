// ComediScanSource against real Comedi kernel drivers (the system test's PREEMPT_RT VM):
//   SEMPOSE_COMEDI_TEST_DEVICE=/dev/comediN  comedi_test, loaded with amplitude=10000000
//       period=1000 (a 10 V, 1 ms sawtooth on AI channel 0): every AI sample's value encodes
//       the time it was taken, so a frame shows exactly which samples landed where.
//   SEMPOSE_COMEDI_SEM_DEVICE=/dev/comediN   sem_emul (tests/system/kmod), with its scene at
//       SEMPOSE_COMEDI_SEM_SCENE: the noise-free detector channel must give back the scene.
// Each group skips, saying why, when its variable is unset (the build machines); the VM sets
// both and fails on any skip.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/ioctl.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sempose/hal/comedi_scan_source.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/clock.hpp"
#include "sempose/rt/frame_pool.hpp"

namespace sempose::hal {
namespace {

const char* env(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? v : nullptr;
}

// Waits like the acquisition thread: poll() the source, sleep in poll(2) on its fd.
PollResult wait_done(ComediScanSource& src, std::int64_t timeout_ns) {
  const std::int64_t end = rt::now_ns() + timeout_ns;
  for (;;) {
    const PollResult r = src.poll();
    if (r != PollResult::kBusy || rt::now_ns() > end) return r;
    pollfd pfd{src.wait_fd(), POLLIN, 0};
    ::poll(&pfd, 1, 1);
  }
}

// ---- comedi_test -----------------------------------------------------------------------

constexpr double kSawPeriodUs = 1000.0;  // module parameter period=1000
constexpr double kSawSpan = 65534.0;     // amplitude 10 V on the ±10 V range: codes 0..65534

config::ComediConfig sawtooth_config(const char* dev) {
  config::ComediConfig c;
  c.device = dev;
  c.detector_channels = {0};  // sawtooth
  c.ai_range = 0;             // ±10 V
  c.x_volts = {-5, 5};
  c.y_volts = {5, -5};
  c.park_volts = {1.5, -2.0};
  c.settle_samples = 3;
  c.flyback_samples = 7;
  c.trigger = "internal";     // comedi_test: AI start TRIG_NOW only, AO start TRIG_INT only
  c.timeout_ms = 2000;        // TCG: its timers fire in 4 ms jiffies, late under load
  return c;
}

// A field, its largest ROI and pixel depth; dwell 1-100 µs in 1 µs steps.
ScanLimits limits(int field_w, int field_h, int max_roi_w, int max_roi_h, int bits) {
  ScanLimits l;
  l.field_w = field_w;
  l.field_h = field_h;
  l.max_roi_w = max_roi_w;
  l.max_roi_h = max_roi_h;
  l.min_dwell_ns = 1000;
  l.max_dwell_ns = 100'000;
  l.dwell_step_ns = 1000;
  l.bits = bits;
  return l;
}

ScanLimits sawtooth_limits() { return limits(64, 48, 64, 48, 16); }

class ComediTestDevice : public ::testing::Test {
 protected:
  void SetUp() override {
    dev_ = env("SEMPOSE_COMEDI_TEST_DEVICE");
    if (dev_ == nullptr) GTEST_SKIP() << "SEMPOSE_COMEDI_TEST_DEVICE not set (a comedi_test device, e.g. /dev/comedi0)";
  }
  const char* dev_ = nullptr;
};

// The sawtooth's time within its period for a sample value, in µs.
double saw_time_us(Pixel v) { return v * kSawPeriodUs / kSawSpan; }

// Checks that pixel (r, c) holds the sample of scan r·per_line + settle + c: the time between
// any two pixels, modulo the sawtooth period, equals their scan distance × the period.
void expect_exact_raster(const Pixel* px, const Roi& roi, const RasterShape& shape, double period_us) {
  const double t0 = saw_time_us(px[0]);
  const int per_line = shape.scans_per_line(roi.w);
  int bad = 0;
  for (int r = 0; r < roi.h; ++r) {
    for (int c = 0; c < roi.w; ++c) {
      const double scans = static_cast<double>(r) * per_line + c;  // relative to pixel (0, 0)
      double d = std::fmod(saw_time_us(px[r * roi.w + c]) - t0 - scans * period_us, kSawPeriodUs);
      if (d > kSawPeriodUs / 2) d -= kSawPeriodUs;
      if (d < -kSawPeriodUs / 2) d += kSawPeriodUs;
      if (std::abs(d) > 0.25 * period_us && ++bad <= 5) {
        ADD_FAILURE() << "pixel (" << r << ", " << c << ") is " << d / period_us
                      << " samples off its place in the raster (lost, duplicated or misplaced sample)";
      }
    }
  }
  EXPECT_EQ(bad, 0);
}

TEST_F(ComediTestDevice, FramesAreExactRowMajorWithoutLostSamplesAndNoAllocation) {
  const config::ComediConfig cfg = sawtooth_config(dev_);
  ComediScanSource src(sawtooth_limits(), cfg);
  EXPECT_EQ(src.timing().min_period_ns, 1000u) << "comedi_test's timers are >= 1 µs";
  FramePool pool(2, 64 * 48);
  const RasterShape shape{cfg.settle_samples, cfg.flyback_samples, 1};
  std::uint64_t seq = 0;
  for (const auto& [roi, dwell] : {std::pair{Roi{5, 7, 32, 24}, 1000u}, std::pair{Roi{0, 0, 64, 48}, 2000u},
                                   std::pair{Roi{40, 30, 24, 18}, 3000u}}) {
    FrameSlot& slot = pool[seq % 2];
    const std::uint64_t allocs = rt::alloc::this_thread_allocations();
    PollResult r;
    {
      rt::alloc::ScopedArm counting;
      ASSERT_EQ(src.start(ScanRequest{roi, dwell, 1}, slot), StartResult::kStarted);
      r = wait_done(src, 5'000'000'000);
    }
    EXPECT_EQ(rt::alloc::this_thread_allocations(), allocs) << "allocation in start()/poll()";
    ASSERT_EQ(r, PollResult::kDone) << "ROI " << roi.w << "x" << roi.h << " at " << dwell << " ns";
    const FrameMeta& m = slot.meta;
    EXPECT_EQ(m.status, FrameStatus::kOk);
    EXPECT_EQ(m.seq, seq++);
    EXPECT_EQ(m.roi, roi);
    EXPECT_EQ(m.dwell_ns, dwell);
    EXPECT_EQ(m.target, 1);
    // Completion is never earlier than the scan itself takes.
    const std::int64_t scan_ns = src.scans_for(roi) * static_cast<std::int64_t>(dwell);
    EXPECT_GE(m.t_scan_end_ns - m.t_scan_start_ns, scan_ns);
    expect_exact_raster(slot.pixels, roi, shape, dwell / 1000.0);
    std::printf("comedi_test: %dx%d at %u ns: %lld scans, scan %.2f ms, completed after %.2f ms, armed in %.1f us\n",
                roi.w, roi.h, dwell, static_cast<long long>(src.scans_for(roi)), scan_ns * 1e-6,
                (m.t_scan_end_ns - m.t_scan_start_ns) * 1e-6, src.counters().last_arm_ns * 1e-3);
  }
  EXPECT_EQ(src.counters().scans, 3u);
}

// Two detector channels and oversampling: the sawtooth (channel 0) and comedi_test's flat
// channel 2 (maxdata / 2) averaged over 2 scans per pixel. 2·pixel − 32767 is then the mean
// of the pixel's two sawtooth samples, i.e. the sawtooth half a sample period after the
// pixel's first scan; a pixel whose two samples straddle the sawtooth's wrap is off by half
// its span, so at most one such pixel per sawtooth period is allowed.
TEST_F(ComediTestDevice, TwoDetectorsAndOversamplingAverageTheRightSamples) {
  config::ComediConfig cfg = sawtooth_config(dev_);
  cfg.detector_channels = {0, 2};
  cfg.oversample = 2;
  ScanLimits lim = sawtooth_limits();
  lim.min_dwell_ns = 2000;
  lim.dwell_step_ns = 2000;
  ComediScanSource src(lim, cfg);
  FramePool pool(1, 64 * 48);
  const Roi roi{3, 4, 32, 24};
  ASSERT_EQ(src.start(ScanRequest{roi, 2000, 0}, pool[0]), StartResult::kStarted);
  ASSERT_EQ(wait_done(src, 5'000'000'000), PollResult::kDone);
  const RasterShape shape{cfg.settle_samples, cfg.flyback_samples, 2};
  const int per_line = shape.scans_per_line(roi.w);
  std::vector<double> t(static_cast<std::size_t>(roi.w * roi.h));
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = (2.0 * pool[0].pixels[i] - 32767.0) * kSawPeriodUs / kSawSpan;
  const double period_us = 1.0;  // sample period: dwell 2000 ns / oversample 2
  int bad = 0;
  for (int r = 0; r < roi.h; ++r) {
    for (int c = 0; c < roi.w; ++c) {
      const double scans = static_cast<double>(r) * per_line + 2.0 * c;
      double d = std::fmod(t[static_cast<std::size_t>(r * roi.w + c)] - t[0] - scans * period_us, kSawPeriodUs);
      if (d > kSawPeriodUs / 2) d -= kSawPeriodUs;
      if (d < -kSawPeriodUs / 2) d += kSawPeriodUs;
      if (std::abs(d) > 0.25 * period_us) ++bad;
    }
  }
  const double frame_us = static_cast<double>(src.scans_for(roi)) * period_us;
  EXPECT_LE(bad, static_cast<int>(frame_us / kSawPeriodUs) + 1) << "pixels off their place in the raster";
  EXPECT_NE(src.description().find("channel(s) 0 2"), std::string::npos) << src.description();
}

TEST_F(ComediTestDevice, CancelMidScanIsABadFrameAndTheNextScanIsExact) {
  const config::ComediConfig cfg = sawtooth_config(dev_);
  ComediScanSource src(sawtooth_limits(), cfg);
  FramePool pool(2, 64 * 48);
  const Roi full{0, 0, 64, 48};  // ~3.6 ms at 1 µs, 36 ms at 10 µs
  ASSERT_EQ(src.start(ScanRequest{full, 10'000, 0}, pool[0]), StartResult::kStarted);
  EXPECT_EQ(src.start(ScanRequest{full, 10'000, 0}, pool[1]), StartResult::kBusy);
  EXPECT_EQ(src.poll(), PollResult::kBusy);
  src.cancel();
  EXPECT_EQ(src.poll(), PollResult::kError);
  EXPECT_EQ(pool[0].meta.status, FrameStatus::kBad);
  EXPECT_EQ(src.poll(), PollResult::kIdle);
  EXPECT_EQ(src.counters().cancelled, 1u);
  const Roi roi{10, 10, 20, 16};
  ASSERT_EQ(src.start(ScanRequest{roi, 1000, 0}, pool[1]), StartResult::kStarted);
  ASSERT_EQ(wait_done(src, 5'000'000'000), PollResult::kDone);
  EXPECT_EQ(pool[1].meta.status, FrameStatus::kOk);
  expect_exact_raster(pool[1].pixels, roi, RasterShape{cfg.settle_samples, cfg.flyback_samples, 1}, 1.0);
}

TEST_F(ComediTestDevice, ParksTheBeamAtTheConfiguredVolts) {
  // comedi_test answers a single AI read with the last value written to the same AO channel.
  const config::ComediConfig cfg = sawtooth_config(dev_);
  std::unique_ptr<ComediScanSource> src = std::make_unique<ComediScanSource>(sawtooth_limits(), cfg);
  ComediDevice probe(dev_);
  auto read_ai = [&](unsigned chan) {
    unsigned data[1] = {0};
    comedi_insn insn{};
    insn.insn = INSN_READ;
    insn.n = 1;
    insn.data = data;
    insn.subdev = 0;
    insn.chanspec = CR_PACK(chan, 0, AREF_GROUND);
    EXPECT_GE(::ioctl(probe.fd(), COMEDI_INSN, &insn), 0);
    return data[0];
  };
  // ±10 V in 65535 codes (comedi_test's AO range 0): 1.5 V -> 37683, -2 V -> 26214.
  EXPECT_NEAR(read_ai(0), 37683.0, 1.0);
  EXPECT_NEAR(read_ai(1), 26214.0, 1.0);
}

TEST_F(ComediTestDevice, RefusesWhatTheCardCannotDoNamingKeyValueAndLimit) {
  auto message = [&](ScanLimits l, config::ComediConfig c) -> std::string {
    try {
      ComediScanSource src(l, c);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(accepted)";
  };
  ScanLimits fast = sawtooth_limits();
  fast.min_dwell_ns = 250;
  fast.dwell_step_ns = 50;
  const std::string m = message(fast, sawtooth_config(dev_));
  EXPECT_NE(m.find("scan.min_dwell_ns: 250"), std::string::npos) << m;
  EXPECT_NE(m.find("1000 ns"), std::string::npos) << m;
  EXPECT_NE(m.find("scan.dwell_step_ns: 50"), std::string::npos) << m;
  config::ComediConfig wide = sawtooth_config(dev_);
  wide.x_volts = {-12, 12};
  const std::string v = message(sawtooth_limits(), wide);
  EXPECT_NE(v.find("comedi.x_volts[0]: -12 V is outside the AO range [-10, 10] V"), std::string::npos) << v;
  config::ComediConfig chan = sawtooth_config(dev_);
  chan.detector_channels = {9};
  const std::string ch = message(sawtooth_limits(), chan);
  EXPECT_NE(ch.find("comedi.detector_channels[0]: 9 is outside [0, 7]"), std::string::npos) << ch;
}

// ---- sem_emul --------------------------------------------------------------------------

class SemEmulDevice : public ::testing::Test {
 protected:
  void SetUp() override {
    dev_ = env("SEMPOSE_COMEDI_SEM_DEVICE");
    scene_path_ = env("SEMPOSE_COMEDI_SEM_SCENE");
    if (dev_ == nullptr || scene_path_ == nullptr) {
      GTEST_SKIP() << "SEMPOSE_COMEDI_SEM_DEVICE / SEMPOSE_COMEDI_SEM_SCENE not set (the emulated SEM)";
    }
  }
  // The whole scene as the field, 8-bit pixels.
  static ScanLimits scene_limits(const Image& scene) { return limits(scene.width, scene.height, 128, 128, 8); }
  // One detector channel, white (5 V) at full scale, field pixel centres on the scene's.
  config::ComediConfig scene_config(const ScanLimits& l, int channel, int timeout_ms) const;
  const char* dev_ = nullptr;
  const char* scene_path_ = nullptr;
};

// sem_emul's beam is on scene pixel floor(code · n / 65536): field pixel c's centre code is
// (c + 0.5) · 65536 / n, i.e. these volts on ±10 V.
double centre_volts(int pixel, int n) { return -10.0 + 20.0 * ((pixel + 0.5) * 65536.0 / n) / 65535.0; }

config::ComediConfig SemEmulDevice::scene_config(const ScanLimits& l, int channel, int timeout_ms) const {
  config::ComediConfig c;
  c.device = dev_;
  c.detector_channels = {channel};
  c.detector_volts = {0.0, 5.0};
  c.x_volts = {centre_volts(0, l.field_w), centre_volts(l.field_w - 1, l.field_w)};
  c.y_volts = {centre_volts(0, l.field_h), centre_volts(l.field_h - 1, l.field_h)};
  c.trigger = "ai_start";
  c.timeout_ms = timeout_ms;
  return c;
}

// One of sem_emul's module parameters ("" when it cannot be read).
std::string sem_param(const char* name) {
  std::ifstream f(std::string("/sys/module/sem_emul/parameters/") + name);
  std::string v;
  f >> v;
  return v;
}

TEST_F(SemEmulDevice, TheNoiseFreeDetectorGivesBackTheSceneAtEveryRoi) {
  const Image scene = read_pgm(scene_path_);
  const ScanLimits l = scene_limits(scene);
  const config::ComediConfig c = scene_config(l, 1, 2000);  // the noise-free channel
  ComediScanSource src(l, c);
  FramePool pool(1, static_cast<std::size_t>(l.field_w) * l.field_h);
  for (const Roi roi : {Roi{0, 0, 96, 80}, Roi{l.field_w - 64, l.field_h - 48, 64, 48}, Roi{123, 77, 128, 128}}) {
    ASSERT_EQ(src.start(ScanRequest{roi, 1000, 0}, pool[0]), StartResult::kStarted);
    ASSERT_EQ(wait_done(src, 10'000'000'000), PollResult::kDone);
    int off = 0;
    for (int r = 0; r < roi.h; ++r) {
      for (int x = 0; x < roi.w; ++x) {
        const int want = scene.pixels[static_cast<std::size_t>((roi.y + r) * scene.width + roi.x + x)];
        const int got = pool[0].pixels[r * roi.w + x];
        if (std::abs(got - want) > 1 && ++off <= 5) {
          ADD_FAILURE() << "ROI at (" << roi.x << ", " << roi.y << ") pixel (" << x << ", " << r << "): " << got
                        << ", scene " << want;
        }
      }
    }
    if (off > 0) {
      ADD_FAILURE() << off << " pixels off in ROI (" << roi.x << ", " << roi.y << ", " << roi.w << "x" << roi.h
                    << "), " << src.scans_for(roi) << " scans; sem_emul: ai " << sem_param("last_ai_scans") << ", ao "
                    << sem_param("last_ao_scans") << ", stale " << sem_param("last_stale_scans");
    }
  }
}

// A real detector integrates the beam current over the dwell, and the tracker expects so (its
// score levels are carried across the governor's dwell changes as r² = S / (S + N), N ∝ 1/dwell):
// sem_emul's noisy channel must hold electrons_white · dwell / ref_dwell_ns electrons at white,
// i.e. a pixel of grey g (white 255) has variance 255 · g / that.
TEST_F(SemEmulDevice, TheNoisyDetectorsDoseFollowsTheDwell) {
  const Image scene = read_pgm(scene_path_);
  const double ew = std::atof(sem_param("electrons_white").c_str());
  const double ref_ns = std::atof(sem_param("ref_dwell_ns").c_str());
  ASSERT_GT(ew, 0) << "sem_emul's electrons_white unreadable";
  ASSERT_GT(ref_ns, 0) << "sem_emul's ref_dwell_ns unreadable";
  const ScanLimits l = scene_limits(scene);
  const config::ComediConfig c = scene_config(l, 0, 5000);  // the noisy channel
  ComediScanSource src(l, c);
  FramePool pool(1, static_cast<std::size_t>(l.field_w) * l.field_h);
  const Roi roi{123, 77, 96, 96};
  double per_grey[2] = {0, 0};
  const std::uint32_t dwells[2] = {16'000, 64'000};  // enough electrons that 0 and 255 rarely clip
  for (int k = 0; k < 2; ++k) {
    ASSERT_EQ(src.start(ScanRequest{roi, dwells[k], 0}, pool[0]), StartResult::kStarted);
    ASSERT_EQ(wait_done(src, 30'000'000'000), PollResult::kDone);
    double sq = 0, grey = 0;
    int n = 0;
    for (int r = 0; r < roi.h; ++r) {
      for (int x = 0; x < roi.w; ++x) {
        const int want = scene.pixels[static_cast<std::size_t>((roi.y + r) * scene.width + roi.x + x)];
        if (want < 40 || want > 160) continue;  // mid-greys: the clipped tails stay below 1 %
        const double d = pool[0].pixels[r * roi.w + x] - want;
        sq += d * d;
        grey += want;
        ++n;
      }
    }
    ASSERT_GT(n, 1000) << "too few mid-grey pixels in the ROI";
    per_grey[k] = sq / grey;
    const double expected = 255.0 / (ew * dwells[k] / ref_ns);
    EXPECT_NEAR(per_grey[k] / expected, 1.0, 0.2)
        << "dwell " << dwells[k] << " ns: variance per grey level " << per_grey[k] << ", expected " << expected
        << " (" << ew << " e- at white at " << ref_ns << " ns)";
  }
  std::printf("sem_emul: variance per grey level %.3f at %lld ns, %.3f at %lld ns (ratio %.2f, 4 expected)\n",
              per_grey[0], static_cast<long long>(dwells[0]), per_grey[1], static_cast<long long>(dwells[1]),
              per_grey[0] / per_grey[1]);
}

// sem_emul's fault injection (module parameters, writable as root).
bool set_sem_param(const char* name, unsigned value) {
  std::ofstream f(std::string("/sys/module/sem_emul/parameters/") + name);
  f << value << "\n";
  f.flush();
  return static_cast<bool>(f);
}

TEST_F(SemEmulDevice, AStalledOrFailedScanIsABadFrameNeverAHang) {
  ScanLimits l;
  l.field_w = 512;
  l.field_h = 384;
  l.max_roi_w = 128;
  l.max_roi_h = 128;
  l.min_dwell_ns = 1000;
  l.dwell_step_ns = 1000;
  config::ComediConfig c;
  c.device = dev_;
  c.detector_channels = {1};
  c.trigger = "ai_start";
  c.timeout_ms = 300;
  ComediScanSource src(l, c);
  FramePool pool(1, 128 * 128);
  const Roi roi{100, 100, 64, 64};
  const std::int64_t scan_ns = src.scans_for(roi) * 1000;  // 5.4 ms

  // A lost clock: samples stop after 500 scans while the command still runs -> the timeout.
  ASSERT_TRUE(set_sem_param("stall_after_scans", 500)) << "cannot write sem_emul's parameters (root?)";
  ASSERT_EQ(src.start(ScanRequest{roi, 1000, 0}, pool[0]), StartResult::kStarted);
  std::int64_t t0 = rt::now_ns();
  EXPECT_EQ(wait_done(src, 10'000'000'000), PollResult::kError);
  // From the source's own scan start (taken before the trigger ioctl) to the failure it
  // reported: the test's t0 comes after start() returned, which under TCG can be ms later.
  const double stalled_ms = (pool[0].meta.t_scan_end_ns - pool[0].meta.t_scan_start_ns) * 1e-6;
  EXPECT_GE(stalled_ms, (scan_ns + 300'000'000) * 1e-6);
  EXPECT_EQ(pool[0].meta.status, FrameStatus::kBad);
  EXPECT_EQ(src.counters().timeouts, 1u);
  set_sem_param("stall_after_scans", 0);

  // An overrun: the command stops with an error after 500 scans -> bad frame without waiting
  // for the timeout.
  ASSERT_TRUE(set_sem_param("fail_after_scans", 500));
  ASSERT_EQ(src.start(ScanRequest{roi, 1000, 0}, pool[0]), StartResult::kStarted);
  t0 = rt::now_ns();
  EXPECT_EQ(wait_done(src, 10'000'000'000), PollResult::kError);
  const double failed_ms = (rt::now_ns() - t0) * 1e-6;
  EXPECT_EQ(src.counters().stopped, 1u);
  EXPECT_EQ(src.counters().timeouts, 1u) << "the early stop must not wait for the timeout";
  set_sem_param("fail_after_scans", 0);
  std::printf("sem_emul: stalled scan reported after %.1f ms (scan %.1f ms + timeout 300 ms), failed scan after %.1f ms\n",
              stalled_ms, scan_ns * 1e-6, failed_ms);

  // And the next scan is whole again.
  ASSERT_EQ(src.start(ScanRequest{roi, 1000, 0}, pool[0]), StartResult::kStarted);
  EXPECT_EQ(wait_done(src, 10'000'000'000), PollResult::kDone);
  EXPECT_EQ(pool[0].meta.status, FrameStatus::kOk);
}

}  // namespace
}  // namespace sempose::hal
