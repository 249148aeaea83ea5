// `sempose view`: an operator's pictures of a run or a recording, from its poses CSV.
//   track.png              x, y, phi and score over time (gnuplot; track.dat/track.gp beside it)
//   roi_<frame>[_<target>].png  with --frames: every Nth pose's ROI from the recorded frames,
//                          the pattern drawn at the reported pose (see roi_overlay.hpp)
// Works on `sempose replay --out` CSVs (frame = index of the PGM in --frames, sorted by name)
// and on `sempose run` CSVs (output.poses_csv; ROI pictures need the frames recorded with
// `sempose sim`). Offline tool: allocates freely, never runs beside the RT stages.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli.hpp"
#include "cli_options.hpp"
#include "cli_signals.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/operator_view/pose_csv.hpp"
#include "sempose/operator_view/roi_overlay.hpp"
#include "sempose/operator_view/track_plot.hpp"
#include "sempose/session/made_folders.hpp"

namespace {

using namespace sempose;

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose view --poses POSES.csv --out DIR [--frames DIR [--pattern P.pgm ...] [--every N]\n"
               "                    [--roi PX] [--pattern-size PX] [--scale K]]\n"
               "  --poses         CSV of sempose run (output.poses_csv) or sempose replay --out\n"
               "  --out           folder for track.png (x, y, phi, score over time) and the ROI pictures\n"
               "  --frames        recorded full-field PGMs (as for replay): draw every Nth pose's ROI\n"
               "  --pattern       each target's pattern, in CSV target order: its edges are drawn at the pose\n"
               "  --every N       one ROI picture per N poses of each target (default 10)\n"
               "  --roi PX        ROI side drawn (default 192); --pattern-size PX without --pattern (default 128)\n"
               "  --scale K       enlarge the ROI pictures K times (default 2)\n");
  return out == stdout ? 0 : 2;
}

// A view stopped by a signal: the pictures it had drawn would look like a whole view of the
// run (a track plot and ROI pictures that end early), so the ones this call wrote are removed
// and the process ends by the signal, as replay and sim do (cli_signals.hpp). Each picture is
// written whole before the signal is looked at, so no cut PNG is left either way.
[[noreturn]] void stop_view(int sig, const std::string& out_dir, const std::vector<std::string>& written,
                            session::MadeFolders& made) {
  std::size_t removed = 0;
  for (const auto& f : written) removed += std::remove(f.c_str()) == 0;
  made.remove_empty();
  char name[24];
  std::fprintf(stderr, "sempose view: stopped by %s; removed the %zu file(s) it had written to %s\n",
               sempose::cli::signal_name(sig, name), removed, out_dir.c_str());
  sempose::cli::end_by_signal(sig);
}

// A file view could not write whole (a full disk, a file-size limit): every file it wrote is
// removed, and the folder when view made it, so no folder that looks like a whole view is left.
int abandon_view(const std::string& why, const std::string& out_dir, const std::vector<std::string>& written,
                 session::MadeFolders& made) {
  std::size_t removed = 0;
  for (const auto& f : written) removed += std::remove(f.c_str()) == 0;
  const bool made_out_dir = made.made(out_dir);
  made.remove_empty();
  std::error_code ec;
  std::fprintf(stderr, "sempose view: %s; removed the %zu file(s) it had written to %s%s\n", why.c_str(), removed,
               out_dir.c_str(), made_out_dir && !std::filesystem::exists(out_dir, ec) ? " and the folder" : "");
  return 1;
}

// The names view writes into --out (and removes there when an earlier view left them).
bool view_writes(const std::filesystem::path& file) {
  const std::string name = file.filename().string();
  return name == "track.dat" || name == "track.gp" || name == "track.png" ||
         (name.rfind("roi_", 0) == 0 && file.extension() == ".png");
}

// A standard stream redirected onto a file view writes (`view --out vv > vv/track.png`): the
// report went into the picture and view said exit 0 (hostile round 10). "" when none is.
std::string stream_onto_output(const std::string& out_dir) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(out_dir, ec)) {
    if (!view_writes(e.path())) continue;
    if (const char* stream = sempose::cli::standard_stream_named(e.path().string()))
      return "this process's " + std::string(stream) + " is " + e.path().string() + ", a file view writes";
  }
  return "";
}

}  // namespace

int sempose::cli::view(int argc, char** argv) {
  const ParsedOptions opt = parse_options({text("--poses", true), text("--out", true), text("--frames"),
                                           text("--pattern", false, true), whole("--every", 1, 1'000'000),
                                           whole("--roi", 8, 4096), whole("--pattern-size", 8, 1024), whole("--scale", 1, 8)},
                                          argc, argv);
  if (const int code = finish_parse("view", opt, usage); code >= 0) return code;
  const std::string poses_path = opt.text("--poses"), out_dir = opt.text("--out"), frames_dir = opt.text("--frames");
  const std::vector<std::string> patterns = opt.all("--pattern");
  const int every = static_cast<int>(opt.whole("--every", 10)), roi = static_cast<int>(opt.whole("--roi", 192)),
            pattern_size = static_cast<int>(opt.whole("--pattern-size", 128)), scale = static_cast<int>(opt.whole("--scale", 2));
  if (cli::refuse_stdout_output("view", out_dir, "the folder the pictures are written to")) return 2;
  if (cli::refuse_control_characters("view", "--out", out_dir)) return 2;
  // A file or device as --out failed after the inputs were read with a bare "filesystem error:
  // cannot create directories: Not a directory [afile]": named by the option, first.
  if (const std::string why = config::output_dir_problem(out_dir); !why.empty()) {
    std::fprintf(stderr, "sempose view: --out: '%s' cannot hold the pictures: it is %s\n", out_dir.c_str(), why.c_str());
    return 2;
  }
  // The pictures go beside the recording, not into it (through a link neither): found probing,
  // `--out REC` wrote track.* and roi_*.png among the frames a replay reads.
  if (!frames_dir.empty()) {
    std::error_code ec;
    if (std::filesystem::equivalent(cli::resolved_output(out_dir), frames_dir, ec) && !ec) {
      std::fprintf(stderr, "sempose view: --out '%s' is the frames folder --frames '%s': the pictures would be written "
                   "into the recording; choose another --out\n", out_dir.c_str(), frames_dir.c_str());
      return 2;
    }
  }
  if (frames_dir.empty() && !patterns.empty()) {
    std::fprintf(stderr, "sempose view: warning: --pattern draws on the ROI pictures, which need --frames: ignored\n");
  }
  // A FIFO as --poses blocked in open() (found probing: the process hung).
  if (const std::string why = config::path_kind_problem(poses_path); !why.empty()) {
    std::fprintf(stderr, "sempose view: --poses: '%s' is %s (need the CSV of a run or a replay)\n", poses_path.c_str(),
                 why.c_str());
    return 2;
  }

  // view writes track.dat/.gp/.png and roi_*.png into --out: an input of such a name there
  // was written over (a poses CSV called track.dat became the plot's data, exit 0).
  std::vector<std::pair<std::string, std::string>> inputs = {{"--poses", poses_path}};
  for (const auto& p : patterns) inputs.emplace_back("--pattern", p);
  for (const auto& [option, path] : inputs) {
    const std::filesystem::path input(path);
    const std::string name = input.filename().string();
    std::error_code ec;
    if (view_writes(input) && std::filesystem::equivalent(std::filesystem::absolute(input, ec).parent_path(), out_dir, ec) && !ec) {
      std::fprintf(stderr, "sempose view: %s '%s' is in --out '%s' under a name view writes (%s): it would be written "
                   "over; choose another --out\n", option.c_str(), path.c_str(), out_dir.c_str(), name.c_str());
      return 2;
    }
  }

  if (const std::string why = stream_onto_output(out_dir); !why.empty()) {
    std::fprintf(stderr, "sempose view: --out '%s': %s; send the report elsewhere\n", out_dir.c_str(),
                 config::terminal_text(why).c_str());
    return 2;
  }

  cli::catch_termination_signals();
  std::vector<std::string> written;  // what this call wrote, removed if a signal stops it
  session::MadeFolders made;         // --out and the folders above it that did not exist
  try {
    const auto rows = operator_view::read_pose_csv(poses_path);
    const auto targets = operator_view::targets_of(rows);
    if (!patterns.empty() && patterns.size() != targets.size()) {
      std::fprintf(stderr, "sempose view: %zu --pattern for %zu target(s) in %s\n", patterns.size(), targets.size(),
                   poses_path.c_str());
      return 2;
    }
    // Inputs are read before anything is written: a bad pattern or frame folder leaves no half output.
    std::vector<hal::Image> pattern_images;
    for (const auto& p : patterns) {
      pattern_images.push_back(hal::read_pgm(p));
      // What run and replay refuse is no pattern of a run to draw (found probing: a 64x32 one
      // was drawn as a 64 px square).
      const hal::Image& im = pattern_images.back();
      if (im.width != im.height) {
        std::fprintf(stderr, "sempose view: --pattern '%s' is %dx%d: a pattern is square (run and replay refuse it)\n",
                     p.c_str(), im.width, im.height);
        return 2;
      }
      if (std::all_of(im.pixels.begin(), im.pixels.end(), [&](auto v) { return v == im.pixels[0]; })) {
        std::fprintf(stderr, "sempose view: --pattern '%s' is flat (every sample %u): no edges to draw (run and replay "
                     "refuse it)\n", p.c_str(), static_cast<unsigned>(im.pixels[0]));
        return 2;
      }
    }
    std::vector<std::string> frame_files;
    if (!frames_dir.empty()) frame_files = hal::list_pgm_frames(frames_dir);
    // The rows a picture is drawn of (every `every`-th pose of each target, up to the last frame
    // the folder holds), and each of their frames read once before anything is written: found
    // probing, a truncated frame 10 ended view with exit 2 after track.* and roi_000000..09.png
    // were written, and a frame of another size than the others was drawn without a word (replay
    // refuses such a recording).
    std::vector<std::size_t> drawn;
    std::size_t beyond_frame = 0;  // a pose of a frame the folder does not hold (0: none)
    if (!frame_files.empty()) {
      std::map<std::string, std::size_t> seen;  // poses per target so far
      for (std::size_t i = 0; i < rows.size(); ++i) {
        if (seen[rows[i].target]++ % static_cast<std::size_t>(every) != 0) continue;
        if (rows[i].frame >= frame_files.size()) {
          beyond_frame = rows[i].frame;
          break;
        }
        drawn.push_back(i);
      }
      std::vector<char> checked(frame_files.size(), 0);
      int first_w = -1, first_h = -1;
      std::string first_file;
      for (const std::size_t i : drawn) {
        const std::size_t f = rows[i].frame;
        if (checked[f]) continue;
        checked[f] = 1;
        const hal::Image img = hal::read_pgm(frame_files[f]);
        if (first_w < 0) {
          first_w = img.width;
          first_h = img.height;
          first_file = frame_files[f];
        } else if (img.width != first_w || img.height != first_h) {
          throw std::runtime_error(frame_files[f] + ": size " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                                   " differs from " + first_file + "'s " + std::to_string(first_w) + "x" +
                                   std::to_string(first_h) + ": not one recording");
        }
        if (const int sig = cli::stop_requested()) stop_view(sig, out_dir, written, made);
      }
    }

    if (const int sig = cli::stop_requested()) stop_view(sig, out_dir, written, made);
    {
      std::error_code ec;  // a folder that cannot be made: named by its option, not a bare filesystem error
      if (!made.make(out_dir, ec)) {
        made.remove_empty();
        std::fprintf(stderr, "sempose view: --out: cannot create the folder '%s' (%s)\n", out_dir.c_str(), ec.message().c_str());
        return 2;
      }
    }
    std::size_t tracked = 0;
    for (const auto& r : rows) tracked += r.status == "TRACKING";
    const std::string title = std::filesystem::path(poses_path).filename().string();  // quoted by plot_track
    for (const char* ext : {".dat", ".gp", ".png"}) written.push_back(out_dir + "/track" + ext);
    std::string plot_problem;
    try {
      plot_problem = operator_view::plot_track(rows, out_dir + "/track", title);
    } catch (const std::exception& e) {
      return abandon_view(cli::error_text(e), out_dir, written, made);
    }
    if (const int sig = cli::stop_requested()) stop_view(sig, out_dir, written, made);

    int pictures = 0;
    std::string first, last;
    try {  // a picture not written whole (write_png removed its cut file) ends the view
      if (!frame_files.empty()) {
        std::size_t outside = 0;  // drawn poses outside their frame
        std::vector<std::vector<std::pair<float, float>>> edges;
        for (const auto& img : pattern_images)
          edges.push_back(operator_view::pattern_edge_points(img));
        if (beyond_frame > 0) {
          std::fprintf(
              stderr,
              "sempose view: pose of frame %llu but %s holds %zu frames; ROI pictures stop there\n",
              static_cast<unsigned long long>(beyond_frame), frames_dir.c_str(),
              frame_files.size());
        }
        for (const std::size_t i : drawn) {
          const operator_view::PoseRow& r = rows[i];
          const std::size_t t = static_cast<std::size_t>(
              std::find(targets.begin(), targets.end(), r.target) - targets.begin());
          const hal::Image frame = hal::read_pgm(frame_files[r.frame]);
          // sempose's poses lie in the field: one outside these frames is from another recording
          // (its pictures used to be drawn of whatever lay there, or of nothing, without a word).
          if (!(r.x_px >= -0.5 && r.x_px <= frame.width - 0.5 && r.y_px >= -0.5 &&
                r.y_px <= frame.height - 0.5) &&
              outside++ == 0) {
            std::fprintf(stderr,
                         "sempose view: warning: the pose of frame %llu at (%g, %g) lies outside "
                         "the %dx%d frames of "
                         "%s: are the poses from this recording?\n",
                         static_cast<unsigned long long>(r.frame), r.x_px, r.y_px, frame.width,
                         frame.height, frames_dir.c_str());
          }
          const int side = pattern_images.empty() ? pattern_size : pattern_images[t].width;
          static const std::vector<std::pair<float, float>> kNoEdges;
          const auto img = operator_view::render_roi(frame, r, roi, side,
                                                     edges.empty() ? kNoEdges : edges[t], scale);
          // A target's name may hold '/' (the config's rule allows it): escaped, with '%' itself,
          // so that every name gives a file of its own in --out (found probing: "a/b" failed after
          // the plot was written).
          char number[24];
          std::snprintf(number, sizeof number, "roi_%06llu",
                        static_cast<unsigned long long>(r.frame));
          std::string name = number;
          if (!r.target.empty()) name += "_";
          for (const char ch : r.target)
            name += ch == '/'   ? std::string("%2F")
                    : ch == '%' ? std::string("%25")
                                : std::string(1, ch);
          name += ".png";
          operator_view::write_png(out_dir + "/" + name, img);
          written.push_back(out_dir + "/" + name);
          if (const int sig = cli::stop_requested()) stop_view(sig, out_dir, written, made);
          if (first.empty()) first = name;
          last = name;
          ++pictures;
        }
      }
    } catch (const std::exception& e) {
      return abandon_view(cli::error_text(e), out_dir, written, made);
    }
    // ROI pictures an earlier view left in --out (a longer run, another --every): they stayed among
    // this view's, a picture of frame 15 that is not this run's frame 15 (found probing). View's
    // own names only (an input of such a name in --out was refused above).
    {
      std::vector<std::filesystem::path> earlier;  // listed first, removed after
      std::error_code ec;
      for (const auto& e : std::filesystem::directory_iterator(out_dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.rfind("roi_", 0) != 0 || !view_writes(e.path()) || !e.is_regular_file(ec)) continue;
        if (std::find(written.begin(), written.end(), out_dir + "/" + name) == written.end()) earlier.push_back(e.path());
      }
      std::sort(earlier.begin(), earlier.end());
      std::size_t stale = 0;
      for (const auto& f : earlier) stale += std::filesystem::remove(f, ec) ? 1 : 0;
      const std::string example = earlier.empty() ? "" : earlier.front().filename().string();
      if (stale > 0) std::printf("view: removed %zu ROI picture(s) an earlier view left in %s (%s ...)\n", stale, out_dir.c_str(), example.c_str());
    }
    std::printf("view: %zu poses, %zu target(s), %.1f%% TRACKING\n", rows.size(), targets.size(), 100.0 * tracked / rows.size());
    if (plot_problem.empty()) std::printf("view: %s/track.png (x, y, phi, score over %s)\n", out_dir.c_str(), "time");
    else std::fprintf(stderr, "sempose view: plot not drawn: %s\n", plot_problem.c_str());  // exit 1: an error, on stderr
    if (pictures > 0) {
      std::printf("view: %d ROI pictures (every %d poses per target): %s/%s ... %s\n", pictures, every, out_dir.c_str(),
                  first.c_str(), last.c_str());
    }
    if (cli::report_lost("view")) return 4;
    return plot_problem.empty() ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sempose view: %s\n", cli::error_text(e).c_str());
    return 2;
  }
}
