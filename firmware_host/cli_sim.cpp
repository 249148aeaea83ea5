// `sempose sim --out DIR [--frames N] [--config FILE] [--seed S] [--dwell NS]`: records a
// simulated sequence in the replay format (README: Replay and recording): full-field frames
// frame_000000.pgm..., frames.csv (frame,t_ns = scan start) and ground_truth.csv
// (frame,x_px,y_px,phi_deg[,target]: each target's pose when the beam passed its pose point,
// in the README's conventions; a full field takes ~78 ms at 640x480, 250 ns, so mid-scan
// would be px off for a moving target).
// Runs on the virtual clock: as fast as the CPU allows and reproducible from the seed.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_signals.hpp"
#include "cli_options.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/scan_config.hpp"
#include "sempose/config/sim_config.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/scan_request_check.hpp"
#include "sempose/hal/sim_source.hpp"
#include "sempose/session/made_folders.hpp"

namespace {

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose sim --out DIR [--frames N] [--config FILE] [--seed S] [--dwell NS]\n"
               "  records N (default 100) full-field simulated frames, frames.csv and ground_truth.csv\n"
               "  --config: a YAML file; its scan: and sim: sections are used\n"
               "  --dwell:  pixel dwell in ns (default 250)\n");
  return out == stdout ? 0 : 2;
}

// Reads only the scan: and sim: sections of the file (the other sections belong to other
// parts of sempose and are validated by `sempose run`).
bool load_sim_sections(const std::string& path, sempose::config::ScanLimits& scan, sempose::config::SimConfig& sim,
                       std::string& error) {
  using namespace sempose::config;
  Errors errors(path);
  YAML::Node root = load_file(path, errors);
  if (errors.empty()) {
    // The sections are copied into a map of their own below, which would drop a repeated
    // `scan:` or `sim:` (the second one was ignored without a word: found probing); the
    // top level's keys are checked for repeats here, as `sempose run` checks them.
    // A key no part of sempose reads (a typo such as `sim_targets:` or `Sim:`) used to be
    // ignored here, and the default scene was recorded: refused as `sempose run` refuses it.
    const std::vector<std::string>& sections = app_config_sections();
    std::string known;
    for (const auto& k : sections) known += (known.empty() ? "" : ", ") + k;
    std::map<std::string, int> first_line;
    for (const auto& kv : root) {
      if (!kv.first.IsScalar()) {
        errors.add(kv.first.Mark(), "(top level)", "a key must be a plain name, not a list or mapping");
        continue;
      }
      const auto [it, fresh] = first_line.emplace(kv.first.Scalar(), kv.first.Mark().line + 1);
      if (!fresh) {
        errors.add(kv.first.Mark(), kv.first.Scalar(), "duplicate key (first given on line " + std::to_string(it->second) + ")");
      } else if (std::find(sections.begin(), sections.end(), kv.first.Scalar()) == sections.end()) {
        errors.add(kv.first.Mark(), kv.first.Scalar(),
                   "unknown key (known: " + known + "; sim reads scan: and sim:, the others are sempose run's)");
      }
    }
  }
  if (errors.empty()) {
    YAML::Node only(YAML::NodeType::Map);
    if (root["scan"]) only["scan"] = root["scan"];
    if (root["sim"]) only["sim"] = root["sim"];
    Section top(only, "", errors);
    {
      Section s = top.child("scan");
      read_scan(s, scan);
    }
    {
      Section s = top.child("sim");
      read_sim(s, sim);
    }
    // Textures beside the config first, as `sempose run` finds them: the scene builder alone
    // looked only in the data folders, and recorded the installed or source tree's file of the
    // same relative name instead of the user's own (found probing).
    if (errors.empty()) resolve_sim_data(top, path, sim, true);
    if (errors.empty()) check_sim_room(top, sim, scan.field_w, scan.field_h);
  }
  error = errors.joined();
  return errors.empty();
}

// Removes what an interrupted recording wrote: its first `frames` frames, the two CSV files
// and the folders this run made (each when nothing else is in it).
void remove_recording(const std::string& dir, unsigned long long frames, sempose::session::MadeFolders& made) {
  std::error_code ec;
  for (unsigned long long f = 0; f < frames; ++f) {
    char name[64];
    std::snprintf(name, sizeof name, "/frame_%06llu.pgm", f);
    std::filesystem::remove(dir + name, ec);
  }
  std::filesystem::remove(dir + "/frames.csv", ec);
  std::filesystem::remove(dir + "/ground_truth.csv", ec);
  made.remove_empty();
}

}  // namespace

int sempose::cli::sim(int argc, char** argv) {
  const ParsedOptions opt = parse_options({text("--out", true), text("--config"), whole("--frames", 1, 1'000'000),
                                           whole("--seed", 0, ~0ULL), whole("--dwell", 1, 100'000'000, "ns")},
                                          argc, argv);
  if (const int code = finish_parse("sim", opt, usage); code >= 0) return code;
  // A signal stops the recording and removes what this run wrote of it (a shorter recording
  // would look whole to replay and pattern): cli_signals.hpp.
  cli::catch_termination_signals();
  const std::string out_dir = opt.text("--out"), config_path = opt.text("--config");
  const unsigned long long frames = opt.whole("--frames", 100), seed = opt.whole("--seed", 0), dwell = opt.whole("--dwell", 250);
  const bool seed_given = opt.has("--seed");
  if (cli::refuse_stdout_output("sim", out_dir, "the folder the recording is written to")) return 2;
  if (cli::refuse_control_characters("sim", "--out", out_dir)) return 2;
  // A file, a device, a folder on a read-only file system: named by the option before the scene is
  // built (it was exit 1 after it, "cannot create frames.csv"; view and pattern refuse it here).
  if (const std::string why = config::output_dir_problem(out_dir); !why.empty()) {
    std::fprintf(stderr, "sempose sim: --out: '%s' cannot hold the recording: it is %s\n", out_dir.c_str(), why.c_str());
    return 2;
  }
  config::ScanLimits scan;
  config::SimConfig sim_cfg;
  if (!config_path.empty()) {
    std::string error;
    if (!load_sim_sections(config_path, scan, sim_cfg, error)) {
      std::fprintf(stderr, "sempose sim: invalid configuration:\n%s", error.c_str());
      return 2;
    }
  }
  if (seed_given) sim_cfg.seed = seed;
  sim_cfg.clock = "virtual";
  {
    // The dwell against the scan limits, as the scans below will check it, before the output
    // folder is made (found probing: `--dwell 1` made the folder, frames.csv and
    // ground_truth.csv, then failed, and that half recording refused the next sim into it), and
    // before the scene is built: a 16384² field took 32 s to build before it was said.
    const hal::Roi whole_field{0, 0, scan.field_w, scan.field_h};
    std::uint32_t rounded = 0;
    if (hal::check_scan_request(scan, {whole_field, static_cast<std::uint32_t>(dwell), 0},
                                static_cast<std::size_t>(scan.field_w) * scan.field_h, rounded) != hal::StartResult::kStarted) {
      std::fprintf(stderr, "sempose sim: --dwell: %llu ns is outside the scan limits [%u, %u] ns (scan.min_dwell_ns, "
                   "scan.max_dwell_ns)\n", dwell, scan.min_dwell_ns, scan.max_dwell_ns);
      return 2;
    }
    // The scan generator sets dwells in steps (found probing: `--dwell 123` with 50 ns steps
    // recorded "dwell 123 ns" for frames scanned at another dwell).
    if (rounded != dwell) {
      std::fprintf(stderr, "sempose sim: --dwell: %llu ns is not a multiple of scan.dwell_step_ns (%u ns): the scan "
                   "generator would scan at %u ns; give a multiple\n", dwell, scan.dwell_step_ns, rounded);
      return 2;
    }
  }
  // The scene first (textures, crops): bad input is named before the output folder is made.
  std::unique_ptr<hal::SimSource> scene;
  try {
    scene = std::make_unique<hal::SimSource>(scan, sim_cfg);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sempose sim: %s\n", cli::error_text(e).c_str());
    return 2;
  }
  {
    // No target (`targets: []`, or every one `enabled: false`): the recording is background
    // only. Useful (a replay of it must report LOST, never TRACKING), so recorded, but said:
    // it used to be made without a word, and a pattern cut from it is of background.
    int enabled = 0;
    for (const auto& t : sim_cfg.targets) enabled += t.enabled ? 1 : 0;
    if (enabled == 0) {
      std::fprintf(stderr, "sempose sim: warning: no target in sim.targets%s: the recording shows the background only "
                   "and ground_truth.csv has no row\n", sim_cfg.targets.empty() ? "" : " is enabled");
    }
  }

  session::MadeFolders made;  // --out and the folders above it that did not exist (removed again on a signal or failure)
  {
    // Frames of an earlier, longer recording would stay beside the new ones (the next replay
    // then fails on a frame without a time stamp, or a pattern averages both): an existing
    // recording is not written over.
    std::error_code ec;
    const auto holds_a_recording = [&] {
      std::size_t old_frames = 0;
      bool old_csv = false;
      if (std::filesystem::is_directory(out_dir, ec)) {
        for (const auto& e : std::filesystem::directory_iterator(out_dir, ec)) {
          old_frames += hal::is_pgm_name(e.path().string()) ? 1 : 0;
          old_csv = old_csv || e.path().filename() == "frames.csv" || e.path().filename() == "ground_truth.csv";
        }
      }
      if (old_frames == 0 && !old_csv) return false;
      std::fprintf(stderr, "sempose sim: --out '%s' already holds a recording (%zu PGM frames%s); remove it or choose another folder\n",
                   out_dir.c_str(), old_frames, old_csv ? ", frames.csv / ground_truth.csv" : "");
      return true;
    };
    if (holds_a_recording()) return 2;
    if (!made.make(out_dir, ec)) {
      std::fprintf(stderr, "sempose sim: --out '%s': cannot make it a folder of frames (%s)\n", out_dir.c_str(),
                   ec ? ec.message().c_str() : "it exists and is not a directory");
      made.remove_empty();
      return 1;
    }
    // Two sims into one folder at once both passed the check above and mixed their frames under
    // one run's frames.csv and truth (found probing). The folder is locked for the recording
    // (held to the process's end) and checked again under the lock: a sim that finished
    // meanwhile left frames there.
    const int lock = ::open(out_dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (lock < 0 || ::flock(lock, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      std::fprintf(stderr, "sempose sim: --out '%s' %s\n", out_dir.c_str(),
                   err == EWOULDBLOCK ? "is being recorded by another sim; choose another folder"
                                      : ("cannot be locked for the recording (" + std::string(std::strerror(err)) + ")").c_str());
      return 2;
    }
    if (holds_a_recording()) return 2;
  }
  unsigned long long frames_started = 0;  // frame files this run may have begun
  try {
    hal::SimSource& source = *scene;
    const hal::Roi field{0, 0, scan.field_w, scan.field_h};
    hal::FramePool pool(1, static_cast<std::size_t>(scan.field_w) * scan.field_h);
    hal::FrameSlot& slot = pool[0];
    std::FILE* frames_csv = std::fopen((out_dir + "/frames.csv").c_str(), "w");
    const int frames_err = errno;
    std::FILE* truth_csv = std::fopen((out_dir + "/ground_truth.csv").c_str(), "w");
    const int truth_err = errno;
    if (!frames_csv || !truth_csv) {
      std::fprintf(stderr, "sempose sim: %s: cannot create %s (%s)\n", out_dir.c_str(),
                   frames_csv ? "ground_truth.csv" : "frames.csv", std::strerror(frames_csv ? truth_err : frames_err));
      if (frames_csv) std::fclose(frames_csv);
      if (truth_csv) std::fclose(truth_csv);
      remove_recording(out_dir, 0, made);
      return 1;
    }
    int enabled = 0;
    for (const auto& t : sim_cfg.targets) enabled += t.enabled ? 1 : 0;
    const bool several = source.target_count() > 1 && enabled > 1;
    std::fprintf(frames_csv, "frame,t_ns\n");
    std::fprintf(truth_csv, several ? "frame,x_px,y_px,phi_deg,target\n" : "frame,x_px,y_px,phi_deg\n");
    hal::Image img;
    img.width = scan.field_w;
    img.height = scan.field_h;
    img.bits = scan.bits;
    img.pixels.resize(static_cast<std::size_t>(scan.field_w) * scan.field_h);
    // Frames each target is in: a target that never enters the field (a typo in `start:`)
    // leaves a recording of background only, and the truth has no row for it.
    std::vector<unsigned long long> in_field(sim_cfg.targets.size(), 0);
    for (unsigned long long f = 0; f < frames; ++f) {
      if (const int sig = cli::stop_requested()) {
        std::fclose(frames_csv);
        std::fclose(truth_csv);
        remove_recording(out_dir, f, made);
        char sname[24];
        std::fprintf(stderr, "sempose sim: stopped by %s after %llu of %llu frames: removed the incomplete recording "
                     "from %s\n", cli::signal_name(sig, sname), f, frames, out_dir.c_str());
        cli::end_by_signal(sig);
      }
      frames_started = f + 1;
      const auto r = source.start({field, static_cast<std::uint32_t>(dwell), 0}, slot);
      if (r != hal::StartResult::kStarted) {
        std::fprintf(stderr, "sempose sim: dwell %llu ns is outside the scan limits [%u, %u] ns\n", dwell,
                     scan.min_dwell_ns, scan.max_dwell_ns);
        std::fclose(frames_csv);
        std::fclose(truth_csv);
        remove_recording(out_dir, f, made);
        return 2;
      }
      while (source.poll() != hal::PollResult::kDone) {
      }
      std::copy(slot.pixels, slot.pixels + img.pixels.size(), img.pixels.begin());
      char name[64];
      std::snprintf(name, sizeof name, "/frame_%06llu.pgm", f);
      hal::write_pgm(out_dir + name, img);
      std::fprintf(frames_csv, "%llu,%lld\n", f, static_cast<long long>(slot.meta.t_scan_start_ns));
      for (int t = 0; t < slot.meta.truth_count; ++t) {
        // A full-field frame takes tens of ms: the truth is the pose when the beam met the target.
        const hal::TargetTruth tr = source.truth_as_scanned(static_cast<std::size_t>(t), field,
                                                            slot.meta.dwell_ns, slot.meta.t_scan_start_ns);
        if (!sim_cfg.targets[static_cast<std::size_t>(t)].enabled || !tr.present) continue;
        ++in_field[static_cast<std::size_t>(t)];
        if (several) {
          std::fprintf(truth_csv, "%llu,%.4f,%.4f,%.4f,%d\n", f, tr.x_px, tr.y_px, tr.phi_deg, t);
        } else {
          std::fprintf(truth_csv, "%llu,%.4f,%.4f,%.4f\n", f, tr.x_px, tr.y_px, tr.phi_deg);
        }
      }
    }
    const bool frames_ok = std::fclose(frames_csv) == 0;
    const bool truth_ok = std::fclose(truth_csv) == 0;  // closed even when the first failed
    if (!frames_ok || !truth_ok) {
      std::fprintf(stderr, "sempose sim: %s: writing the CSV files failed (disk full?); removed the incomplete "
                   "recording\n", out_dir.c_str());
      remove_recording(out_dir, frames, made);
      return 1;
    }
    for (std::size_t t = 0; t < in_field.size(); ++t) {
      if (!sim_cfg.targets[t].enabled || in_field[t] == frames) continue;
      std::fprintf(stderr, "sempose sim: warning: target %zu (start [%g, %g]) is in the %dx%d field on %llu of %llu frames%s\n", t,
                   sim_cfg.targets[t].x_px, sim_cfg.targets[t].y_px, scan.field_w, scan.field_h, in_field[t], frames,
                   in_field[t] == 0 ? "; the recording shows only background for it and the truth has no row for it" : "");
    }
    std::printf("sempose sim: wrote %llu frames (%dx%d, %u-bit, dwell %llu ns) to %s\n", frames, scan.field_w,
                scan.field_h, static_cast<unsigned>(scan.bits), dwell, out_dir.c_str());
  } catch (const std::exception& e) {
    // A frame that could not be written (a full disk): the recording so far is removed, as on
    // a signal — it left a cut PGM, empty CSV files, and a folder the next sim refused.
    std::fprintf(stderr, "sempose sim: %s; removed the incomplete recording from %s\n", cli::error_text(e).c_str(), out_dir.c_str());
    remove_recording(out_dir, frames_started, made);
    return 1;
  }
  // The recording is whole; only the line saying so was lost (found probing: `> /dev/full`
  // exited 0 with nothing said). Exit 4, as pattern, view and replay do.
  return cli::report_lost("sim") ? 4 : 0;
}
