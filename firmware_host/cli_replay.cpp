// `sempose replay --frames DIR --pattern P.pgm [--mask M.pgm] [--pattern Q.pgm ...] [--config FILE]
//                 [--truth ground_truth.csv] --out poses.csv`
// Tracks through a recorded sequence (README: Replay and recording) exactly as on the microscope: every
// target's tracker asks for its next ROI, gets it as a crop of the current full-field frame,
// and starts with a full-field search (no start pose needed). Writes
// frame,t_ns,x_px,y_px,phi_deg,score,status[,target] and ends with one line
//   summary: frames=N tracked_share=F compute_us_p50=A compute_us_p99=B compute_us_max=C acquire_ms=D
// compute = the tracker's update() per tracked-ROI pose (correlation + orientation), file I/O
// excluded; acquire = the first full-field search. With --truth: RMS/max position and angle
// errors over TRACKING poses, on a line before the summary.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/pipeline/pose_input.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/tracker_config.hpp"
#include "sempose/hal/frames_csv.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/pipeline/pose_input.hpp"
#include "sempose/pipeline/tracker_setup.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/clock.hpp"

namespace {

using namespace sempose;

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose replay --frames DIR --pattern P.pgm [--mask M.pgm] [--pattern Q.pgm ...] [--config FILE]\n"
               "                      [--truth ground_truth.csv] --out poses.csv\n"
               "  tracks every pattern (one target each) through the recorded full-field frames in DIR\n"
               "  --config: YAML; its tracker: section (and targets:, when no --pattern is given) are used\n"
               "  --mask:   the preceding pattern's shape mask (PGM, same size; non-zero = the target)\n"
               "  --truth:  frame,x_px,y_px,phi_deg[,target]; prints RMS/max errors\n");
  return out == stdout ? 0 : 2;
}

struct Target {
  std::string name;
  std::unique_ptr<pose::Tracker> tracker;
};

struct Truth {
  double x = 0, y = 0, phi = 0;
};

// frame,t_ns (frames.csv) or frame,x,y,phi[,target] (ground truth): numeric rows after a header.
std::vector<std::vector<double>> read_numeric_csv(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open");
  std::vector<std::vector<double>> rows;
  std::string line;
  int n = 0;
  while (std::getline(f, line)) {
    if (++n == 1 || line.empty()) continue;
    std::vector<double> row;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str()) throw std::runtime_error(path + ":" + std::to_string(n) + ": '" + cell + "' is not a number");
      row.push_back(v);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5))];
}

int run_replay(int argc, char** argv) {
  std::string frames_dir, config_path, truth_path, out_path;
  std::vector<std::string> patterns, masks;  // masks[i]: --mask after pattern i ("" = none)
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](std::string& dst) {
      if (i + 1 >= argc) throw std::runtime_error(a + " needs a value");
      dst = argv[++i];
    };
    if (a == "--help" || a == "-h") return usage(stdout);
    if (a == "--frames") value(frames_dir);
    else if (a == "--config") value(config_path);
    else if (a == "--truth") value(truth_path);
    else if (a == "--out") value(out_path);
    else if (a == "--pattern") {
      std::string p;
      value(p);
      patterns.push_back(p);
      masks.emplace_back();
    } else if (a == "--mask") {
      if (patterns.empty()) {
        std::fprintf(stderr, "sempose replay: --mask must follow the --pattern it belongs to\n");
        return usage(stderr);
      }
      value(masks.back());
    } else {
      std::fprintf(stderr, "sempose replay: unknown option '%s'\n", a.c_str());
      return usage(stderr);
    }
  }
  if (frames_dir.empty() || out_path.empty()) return usage(stderr);

  config::TrackerConfig tracker_cfg;
  std::vector<config::TargetConfig> targets_cfg;
  if (!config_path.empty()) {
    config::AppConfig app;
    std::string errors;
    if (!config::load_app_config(config_path, app, errors)) {
      std::fprintf(stderr, "sempose replay: %s", errors.c_str());
      return 2;
    }
    tracker_cfg = app.tracker;
    targets_cfg = app.targets;
  }
  if (!patterns.empty()) {
    targets_cfg.clear();
    for (std::size_t i = 0; i < patterns.size(); ++i) {
      config::TargetConfig t;
      t.name = std::filesystem::path(patterns[i]).stem().string();
      t.pattern_sets.push_back({patterns[i], 1.0, masks[i]});
      targets_cfg.push_back(t);
    }
  }
  if (targets_cfg.empty()) {
    std::fprintf(stderr, "sempose replay: no pattern: give --pattern P.pgm or targets: in --config\n");
    return 2;
  }
  if (targets_cfg.size() > static_cast<std::size_t>(hal::kMaxTargets)) {
    std::fprintf(stderr, "sempose replay: %zu targets, at most %d\n", targets_cfg.size(), hal::kMaxTargets);
    return 2;
  }

  const std::vector<std::string> names = hal::list_pgm_frames(frames_dir);
  hal::Image frame = hal::read_pgm(names.front());
  hal::ScanLimits limits;
  limits.field_w = frame.width;
  limits.field_h = frame.height;
  limits.bits = frame.bits;

  std::vector<Target> targets;
  for (const auto& tc : targets_cfg) {
    std::vector<pose::PatternSet> sets;
    for (const auto& ps : tc.pattern_sets) {
      pose::PatternSet set;
      const rt::Status loaded = pipeline::load_pattern_set(ps, set);
      if (!loaded.ok) {
        std::fprintf(stderr, "sempose replay: target '%s': %s\n", tc.name.c_str(), loaded.message.c_str());
        return 2;
      }
      sets.push_back(std::move(set));
    }
    rt::Status st;
    Target t{tc.name, pose::Tracker::create(tracker_cfg, std::move(sets), limits, st)};
    if (!t.tracker) {
      std::fprintf(stderr, "sempose replay: target '%s': %s\n", tc.name.c_str(), st.message.c_str());
      return 2;
    }
    if (!st.message.empty()) std::fprintf(stderr, "%s\n", st.message.c_str());
    std::fprintf(stderr, "target '%s': pattern bank, spectra and buffers %.1f MB\n", tc.name.c_str(),
                 t.tracker->memory_bytes() / 1e6);
    targets.push_back(std::move(t));
  }

  std::vector<std::int64_t> t_ns;
  const std::string frames_csv = (std::filesystem::path(frames_dir) / "frames.csv").string();
  if (std::filesystem::exists(frames_csv)) t_ns = hal::read_frames_csv(frames_csv, names.size());
  std::map<std::pair<long, int>, Truth> truth;
  if (!truth_path.empty()) {
    for (const auto& r : read_numeric_csv(truth_path)) {
      if (r.size() < 4) throw std::runtime_error(truth_path + ": expected frame,x_px,y_px,phi_deg[,target]");
      // A row naming no frame or target, or with a non-finite value, is not truth (and a NaN
      // or huge value must not reach an integer conversion).
      if (!(std::fabs(r[0]) < 1e15) || (r.size() >= 5 && !(std::fabs(r[4]) < 1e6)) || !std::isfinite(r[1]) ||
          !std::isfinite(r[2]) || !std::isfinite(r[3])) {
        continue;
      }
      truth[{static_cast<long>(r[0]), r.size() >= 5 ? static_cast<int>(r[4]) : 0}] = {r[1], r[2], r[3]};
    }
  }

  std::FILE* out = std::fopen(out_path.c_str(), "w");
  if (!out) throw std::runtime_error(out_path + ": cannot write");
  const bool multi = targets.size() > 1;
  std::fprintf(out, "frame,t_ns,x_px,y_px,phi_deg,score,status%s\n", multi ? ",target" : "");

  std::vector<hal::Pixel> crop(static_cast<std::size_t>(frame.width) * frame.height);
  std::vector<double> compute_us;
  compute_us.reserve(names.size() * targets.size());
  double acquire_ms = -1;
  long poses = 0, tracked = 0;
  double sum_px2 = 0, max_px = 0, sum_deg2 = 0, max_deg = 0;
  long err_n = 0;
  for (std::size_t f = 0; f < names.size(); ++f) {
    if (f > 0) frame = hal::read_pgm(names[f]);
    if (frame.width != limits.field_w || frame.height != limits.field_h) {
      throw std::runtime_error(names[f] + ": " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                               " differs from the first frame's " + std::to_string(limits.field_w) + "x" +
                               std::to_string(limits.field_h) + " (all frames must share one size)");
    }
    const std::int64_t t_frame = f < t_ns.size() ? t_ns[f] : 0;
    for (std::size_t k = 0; k < targets.size(); ++k) {
      pose::Tracker& tr = *targets[k].tracker;
      hal::FrameMeta meta;
      meta.seq = f;
      meta.roi = tr.next_roi();
      meta.field_w = frame.width;
      meta.field_h = frame.height;
      meta.bits = frame.bits;
      meta.target = static_cast<std::uint8_t>(k);
      meta.t_scan_start_ns = t_frame;
      for (int y = 0; y < meta.roi.h; ++y) {
        std::memcpy(crop.data() + static_cast<std::size_t>(y) * meta.roi.w,
                    frame.pixels.data() + static_cast<std::size_t>(meta.roi.y + y) * frame.width + meta.roi.x,
                    sizeof(hal::Pixel) * static_cast<std::size_t>(meta.roi.w));
      }
      const std::int64_t t0 = rt::now_ns();
      const pose::PoseEstimate e = tr.update(pipeline::to_pose_frame(meta, crop.data()));
      const double us = (rt::now_ns() - t0) * 1e-3;
      tr.maintain_appearance();  // offline: the appearance rebuild runs between frames
      if (e.searched) {
        if (acquire_ms < 0) acquire_ms = us * 1e-3;
      } else {
        compute_us.push_back(us);
      }
      ++poses;
      if (e.state == pose::TrackState::kTracking) ++tracked;
      std::fprintf(out, "%zu,%lld,%.4f,%.4f,%.4f,%.5f,%s", f, static_cast<long long>(t_frame), e.x_px, e.y_px,
                   e.phi_deg, static_cast<double>(e.score), pose::to_string(e.state));
      if (multi) std::fprintf(out, ",%s", targets[k].name.c_str());
      std::fputc('\n', out);
      const auto it = truth.find({static_cast<long>(f), static_cast<int>(k)});
      if (it != truth.end() && e.state == pose::TrackState::kTracking) {
        const double d = std::hypot(e.x_px - it->second.x, e.y_px - it->second.y);
        const double a = std::fabs(std::fmod(e.phi_deg - it->second.phi + 540.0, 360.0) - 180.0);
        sum_px2 += d * d;
        sum_deg2 += a * a;
        max_px = std::max(max_px, d);
        max_deg = std::max(max_deg, a);
        ++err_n;
      }
    }
  }
  std::fclose(out);
  if (!truth_path.empty()) {
    std::printf("truth: poses_compared=%ld rms_px=%.4f max_px=%.4f rms_deg=%.4f max_deg=%.4f\n", err_n,
                err_n ? std::sqrt(sum_px2 / err_n) : 0.0, max_px, err_n ? std::sqrt(sum_deg2 / err_n) : 0.0, max_deg);
  }
  std::printf("summary: frames=%zu tracked_share=%.4f compute_us_p50=%.1f compute_us_p99=%.1f compute_us_max=%.1f "
              "acquire_ms=%.2f\n",
              names.size(), poses ? static_cast<double>(tracked) / poses : 0.0, percentile(compute_us, 0.5),
              percentile(compute_us, 0.99), compute_us.empty() ? 0.0 : *std::max_element(compute_us.begin(), compute_us.end()),
              std::max(0.0, acquire_ms));
  return 0;
}

}  // namespace

int sempose::cli::replay(int argc, char** argv) {
  try {
    return run_replay(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sempose replay: %s\n", e.what());
    return 2;
  }
}
