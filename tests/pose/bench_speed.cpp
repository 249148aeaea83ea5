// Speed: per-pose compute with orientation (FFT correlation at the predicted angle, the
// walk's j±1, sub-pixel and sub-degree fits) for a 128² pattern in 144², 160², 192² ROIs (not
// 128²: an ROI of the pattern's size is refused),
// side by side with OpenCV matchTemplate(TM_CCOEFF_NORMED) doing the same 3-angle search
// (8-bit input, its fastest path; no mask). Start search on 640x480 and 1024x768. Medians of
// repeated runs in one process; the ratio is what counts (same machine, same moment).
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdlib>
#include <string>
#include <cstdio>
#include <ctime>
#include <vector>

#include "sempose/pose/attainable_score.hpp"
#include "sempose/pose/bicubic_rotate.hpp"
#include "sempose/pose/window_noise.hpp"
#include "sim_harness.hpp"

using namespace sempose;
using namespace sempose::pose;
using namespace sempose::pose::testing;

namespace {

struct Timing {
  double p50_us, p99_us, max_us;
  double cpu_p50_us;  // the process's CPU time, all threads (the machine is shared: wall time includes waiting)
};

std::int64_t process_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

template <typename F>
Timing time_it(int reps, F&& f) {
  std::vector<double> us, cpu;
  us.reserve(static_cast<std::size_t>(reps));
  cpu.reserve(static_cast<std::size_t>(reps));
  for (int i = 0; i < reps; ++i) {
    const std::int64_t c0 = process_cpu_ns();
    const std::int64_t t0 = rt::now_ns();
    f();
    us.push_back((rt::now_ns() - t0) * 1e-3);
    cpu.push_back((process_cpu_ns() - c0) * 1e-3);
  }
  std::sort(us.begin(), us.end());
  std::sort(cpu.begin(), cpu.end());
  return {us[us.size() / 2], us[std::min(us.size() - 1, us.size() * 99 / 100)], us.back(), cpu[cpu.size() / 2]};
}

}  // namespace

int main(int argc, char** argv) {
  // --profile ROI [REPS]: only the tracker's per-pose loop at that ROI (for perf record).
  const int profile_roi = argc > 2 && std::string(argv[1]) == "--profile" ? std::atoi(argv[2]) : 0;
  const int profile_reps = argc > 3 ? std::atoi(argv[3]) : 20000;
  // --profile-search W H one|levels|narrow [REPS]: only the start search at that field (perf).
  const bool profile_search = argc > 4 && std::string(argv[1]) == "--profile-search";
  const int ps_w = profile_search ? std::atoi(argv[2]) : 0, ps_h = profile_search ? std::atoi(argv[3]) : 0;
  const std::string ps_cover = profile_search ? argv[4] : "";
  const int ps_reps = profile_search && argc > 5 ? std::atoi(argv[5]) : 400;
  // The peer's threads: matchTemplate may split its work over OpenCV's pool; the CPU column
  // (all threads' CPU time) is the per-thread comparison, the wall ratio the one a user sees.
  std::printf("per-pose compute with orientation, pattern 128², 3 angles (median / p99 over runs; OpenCV threads %d)\n",
              cv::getNumThreads());
  std::printf("%-6s | %12s %12s | %14s | %7s\n", "ROI", "sempose p50", "sempose p99", "matchTemplate", "ratio");
  for (int roi : {144, 160, 192}) {
    if ((profile_roi && roi != profile_roi) || profile_search) continue;
    config::TrackerConfig tc;
    tc.roi_size_px = roi;
    Scenario s;
    s.motion = "static";
    s.dose_e = 6;
    s.frames = 4;
    SimHarness h(s, tc);
    if (!h.status().ok) {
      std::printf("setup failed: %s\n", h.status().message.c_str());
      return 1;
    }
    h.run();
    Tracker& t = *h.tracker();
    // One ROI frame at the tracked pose, replayed (the tracker re-tracks it each time).
    hal::FrameMeta meta;
    meta.roi = t.next_roi();
    meta.field_w = s.field_w;
    meta.field_h = s.field_h;
    config::SimConfig sc = make_sim_config(s);
    hal::ScanLimits lim;
    lim.field_w = s.field_w;
    lim.field_h = s.field_h;
    hal::SimSource sim(lim, sc);
    std::vector<hal::Pixel> px(static_cast<std::size_t>(meta.roi.w) * meta.roi.h);
    sim.render(meta.roi, 250, hal::SimSource::kVirtualEpochNs, 1, px.data(), meta.truth);
    // A second scan of the same place (another noise stream): the frames alternate, as a tracker
    // handed the very same pixels twice holds the second as a frozen frame (stale_frame_check.hpp).
    std::vector<hal::Pixel> px2(px.size());
    sim.render(meta.roi, 250, hal::SimSource::kVirtualEpochNs, 2, px2.data(), meta.truth);
    unsigned flip = 0;
    const auto scan = [&] { return (++flip & 1u) ? px.data() : px2.data(); };
    int tracked = 0;
    if (profile_roi) {
      const Timing p = time_it(profile_reps, [&] { tracked += t.update(pipeline::to_pose_frame(meta, scan())).state == TrackState::kTracking; });
      std::printf("%3d²   | %9.1f us %9.1f us | tracked %d/%d, CPU p50 %.1f us\n", roi, p.p50_us, p.p99_us, tracked, profile_reps,
                  p.cpu_p50_us);
      return 0;
    }
    const Timing ours = time_it(400, [&] { tracked += t.update(pipeline::to_pose_frame(meta, scan())).state == TrackState::kTracking; });

    // The peer: three rotated 8-bit patterns against the 8-bit ROI.
    cv::Mat roi8(meta.roi.h, meta.roi.w, CV_8U);
    for (int i = 0; i < meta.roi.w * meta.roi.h; ++i) roi8.data[i] = static_cast<std::uint8_t>(std::min<int>(px[i], 255));
    const hal::Image pat = hal::render_sim_pattern(sc, lim, 0, 128, 10, 250, 777);
    std::vector<float> src(pat.pixels.begin(), pat.pixels.end()), rot(src.size());
    std::vector<cv::Mat> pats;
    for (double a : {-1.0, 0.0, 1.0}) {
      rotate_pattern(src.data(), 128, a, rot.data());
      cv::Mat m(128, 128, CV_8U);
      for (int i = 0; i < 128 * 128; ++i) m.data[i] = static_cast<std::uint8_t>(std::clamp(rot[i], 0.0f, 255.0f));
      pats.push_back(m);
    }
    cv::Mat result;
    double peer_best = 0;
    const Timing peer = time_it(60, [&] {
      for (const auto& p : pats) {
        cv::matchTemplate(roi8, p, result, cv::TM_CCOEFF_NORMED);
        double mx = 0;
        cv::minMaxLoc(result, nullptr, &mx);
        peer_best = std::max(peer_best, mx);
      }
    });
    std::printf("%3d²   | %9.1f us %9.1f us | %11.1f us | %6.1fx   (tracked %d/400, peer score %.2f; CPU p50 %.1f vs %.1f us: %.1fx)\n",
                roi, ours.p50_us, ours.p99_us, peer.p50_us, peer.p50_us / ours.p50_us, tracked, peer_best, ours.cpu_p50_us,
                peer.cpu_p50_us, peer.cpu_p50_us / ours.cpu_p50_us);
    if (roi == 192) {
      // The attainable score alone (the tracker runs it when a tracked score is below 0.7 and on
      // every start-search match): the line-correlated noise model, beside Immerkær's white-noise
      // estimator (what it replaced) on the same 128² window of this ROI.
      const PrefilterNoiseGain gain(tc.prefilter_passes);
      const double c = (roi - 1) / 2.0;
      const int x0 = (roi - 128) / 2;
      double sink = 0;
      const Timing att = time_it(4000, [&] { sink += attainable_score(px.data(), roi, roi, c, c, 128, gain).score; });
      const Timing imm = time_it(4000, [&] { sink += window_noise_var(px.data(), roi, x0, x0, 128); });
      std::printf("%3d²   | %9.1f us %9.1f us | %11.1f us |          attainable score alone (line-correlated noise; right: Immerkær's white-noise estimator alone)%s\n",
                  roi, att.p50_us, att.p99_us, imm.p50_us, sink > 0 ? "" : " ");
      // An option's cost: the same frames replayed by a tracker set up with it; its ratio to the
      // default tracker's p50 in this run.
      const auto time_option = [&](const config::TrackerConfig& with, const std::string& what) {
        SimHarness ho(s, with);
        ho.run();
        Tracker& tko = *ho.tracker();
        int tracked_o = 0;
        const Timing opt =
            time_it(400, [&] { tracked_o += tko.update(pipeline::to_pose_frame(meta, scan())).state == TrackState::kTracking; });
        std::printf("%3d²   | %9.1f us %9.1f us | %11.1f us | %6.1fx   %s: %.2fx the default's p50 (tracked %d/400)\n", roi,
                    opt.p50_us, opt.p99_us, peer.p50_us, peer.p50_us / opt.p50_us, what.c_str(), opt.p50_us / ours.p50_us,
                    tracked_o);
      };
      // The final Gauss–Newton fit (tracker.refine on), each source.
      for (const char* source : {"prefiltered", "raw"}) {
        config::TrackerConfig tr = tc;
        tr.refine.enabled = true;
        tr.refine.source = source;
        time_option(tr, std::string("tracker.refine on, source ") + source);
      }
      // The background plane (off by default): its share of the fits it is significant in.
      config::TrackerConfig tp = tc;
      tp.fit_background_plane = true;
      time_option(tp, "tracker.fit_background_plane on");
      // Learned appearance: a tracker that learned its support over 120 moving frames, then the
      // same replay (each update also feeds the appearance observer: its RT cost is included).
      config::TrackerConfig ta = tc;
      ta.appearance.enabled = true;
      Scenario m = s;
      m.motion = "smooth";
      m.frames = 120;
      SimHarness ha(m, ta);
      ha.run();
      Tracker& tl = *ha.tracker();
      hal::FrameMeta ml = meta;
      ml.roi = tl.next_roi();
      std::vector<hal::Pixel> pl(static_cast<std::size_t>(ml.roi.w) * ml.roi.h), pl2(pl.size());
      ha.render(ml.roi, ha.records().back().t_start_ns + 10'000'000, 1u << 20, pl.data(), ml.truth);
      ha.render(ml.roi, ha.records().back().t_start_ns + 10'000'000, (1u << 20) + 1, pl2.data(), ml.truth);
      int tracked_l = 0;
      const Timing learned =
          time_it(400, [&] { tracked_l += tl.update(pipeline::to_pose_frame(ml, (++flip & 1u) ? pl.data() : pl2.data())).state == TrackState::kTracking; });
      const Tracker::AppearanceStatus a = tl.appearance_status();
      std::printf("%3d²   | %9.1f us %9.1f us | %11.1f us | %6.1fx   learned appearance (%u updates, support %.2f of the circle; tracked %d/400)\n",
                  roi, learned.p50_us, learned.p99_us, peer.p50_us, peer.p50_us / learned.p50_us, a.accepted,
                  a.support_fraction, tracked_l);
    }
  }

  std::printf("\nstart search (full field, x8 pyramid, 18 coarse angles, 4 candidates refined; scale 1 only =\n"
              "tracker.search_scale_min = max = 1; 0.75-1.33 = a new target, no SELECT: levels 0.8, 1, 1.25 around the\n"
              "expected scale; narrow = a SELECT gave nm/px: one level, refined +-14.8 %%)\n");
  enum class Cover { kScaleOne, kLevels, kNarrow };
  for (auto [w, hgt] : {std::pair{640, 480}, std::pair{1024, 768}})
  for (const Cover cover : {Cover::kScaleOne, Cover::kLevels, Cover::kNarrow}) {
    const char* cover_name = cover == Cover::kLevels ? "levels" : cover == Cover::kNarrow ? "narrow" : "one";
    if (profile_search && (w != ps_w || hgt != ps_h || ps_cover != cover_name)) continue;
    config::TrackerConfig tc;
    if (cover == Cover::kScaleOne) tc.search_scale_min = tc.search_scale_max = 1.0;
    Scenario s;
    s.motion = "static";
    s.dose_e = 6;
    s.frames = 1;
    s.field_w = w;
    s.field_h = hgt;
    s.start_x_px = w * 0.3;
    s.start_y_px = hgt * 0.6;
    s.start_phi_deg = 77;
    SimHarness h(s, tc);
    h.run();
    Tracker& t = *h.tracker();
    if (cover == Cover::kNarrow) t.select_pattern_set(0, t.nm_per_px());  // told: the pattern's own size
    hal::FrameMeta meta;
    meta.roi = {0, 0, w, hgt};
    meta.field_w = w;
    meta.field_h = hgt;
    config::SimConfig sc = make_sim_config(s);
    hal::ScanLimits lim;
    lim.field_w = w;
    lim.field_h = hgt;
    hal::SimSource sim(lim, sc);
    std::vector<hal::Pixel> px(static_cast<std::size_t>(w) * hgt), px2(px.size());
    sim.render(meta.roi, 250, hal::SimSource::kVirtualEpochNs, 1, px.data(), meta.truth);
    sim.render(meta.roi, 250, hal::SimSource::kVirtualEpochNs, 2, px2.data(), meta.truth);  // alternated: not a frozen frame
    unsigned flip = 0;
    int found = 0;
    const Timing ts = time_it(profile_search ? ps_reps : 15, [&] {
      // A full-field frame while tracking is otherwise tracked in its crop. Found: the search's
      // pose is followed and within 1 px. Its state is not asked: with no ROI frame between the
      // searches the stream's noise is never learnt, so each search frame waits, UNCERTAIN, for
      // an ROI frame to confirm it (README: States), as a controller's command's does too.
      t.request_reacquire(/*commanded=*/false);
      const PoseEstimate e = t.update(pipeline::to_pose_frame(meta, (++flip & 1u) ? px.data() : px2.data()));
      found += e.searched && e.followed && std::hypot(e.x_px - meta.truth[0].x_px, e.y_px - meta.truth[0].y_px) < 1.0;
    });
    std::printf("%4dx%-4d  %-13s p50 %7.2f ms  max %7.2f ms  CPU p50 %6.2f ms  found %d/%d   (bank + buffers %.1f MB)\n", w, hgt,
                cover == Cover::kLevels ? "0.75-1.33" : cover == Cover::kNarrow ? "narrow" : "scale 1 only", ts.p50_us * 1e-3, ts.max_us * 1e-3, ts.cpu_p50_us * 1e-3, found, profile_search ? ps_reps : 15, t.memory_bytes() / 1e6);
  }
  return 0;
}
