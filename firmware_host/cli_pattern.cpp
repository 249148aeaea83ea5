// `sempose pattern --frames DIR --center X,Y [--size 128] [--average 10] --out P.pgm`: a
// pattern as the paper made it: the mean of the first N recorded frames, cropped so that the
// pattern's centre pixel ((size-1)/2, (size-1)/2) lies at (X, Y) (README: Conventions). A crop that
// falls between pixels is bilinearly interpolated. Only the leading frames in which the window
// stands still are averaged (pattern_stillness.hpp): a moving target would be smeared.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "cli.hpp"
#include "cli_signals.hpp"
#include "cli_options.hpp"
#include "pattern_stillness.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/tracker_config.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/replay_source.hpp"
#include "sempose/pose/pattern_rim.hpp"

namespace {

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose pattern --frames DIR --center X,Y [--size 128] [--average 10] --out P.pgm\n"
               "  averages the first N frames of DIR (sorted *.pgm) and crops size x size around (X, Y);\n"
               "  stops at the first frame in which the window moved or changed beyond its noise\n");
  return out == stdout ? 0 : 2;
}

[[noreturn]] void stopped_by(int sig, std::size_t done, std::size_t n, const std::string& out) {
  char name[24];
  std::fprintf(stderr, "sempose pattern: stopped by %s after %zu of %zu frames: %s not written\n",
               sempose::cli::signal_name(sig, name), done, n, out.c_str());
  sempose::cli::end_by_signal(sig);
}

}  // namespace

int sempose::cli::pattern(int argc, char** argv) {
  const ParsedOptions opt = parse_options({text("--frames", true), text("--center", true), text("--out", true),
                                           whole("--size", 4, 4096), whole("--average", 1, 100000)},
                                          argc, argv);
  if (const int code = finish_parse("pattern", opt, usage); code >= 0) return code;
  // A signal while the frames are read stops before the pattern is written; one while it is
  // written waits until the file is whole (cli_signals.hpp).
  cli::catch_termination_signals();
  const std::string dir = opt.text("--frames"), out = opt.text("--out"), center = opt.text("--center");
  const long size = static_cast<long>(opt.whole("--size", 128)), average = static_cast<long>(opt.whole("--average", 10));
  if (cli::refuse_stdout_output("pattern", out, "the pattern's PGM file")) return 2;
  if (cli::refuse_control_characters("pattern", "--out", out)) return 2;
  // A folder or device as --out failed after every frame was read with "cannot create the file".
  if (const std::string why = config::output_path_problem(out); !why.empty()) {
    std::fprintf(stderr, "sempose pattern: --out: '%s' cannot take the pattern: it is %s\n", out.c_str(), why.c_str());
    return 2;
  }
  double cx = 0, cy = 0;
  {
    const auto comma = center.find(',');
    const std::string xs = center.substr(0, comma), ys = comma == std::string::npos ? "" : center.substr(comma + 1);
    if (comma == std::string::npos || !parse_real(xs, cx) || !parse_real(ys, cy)) {
      std::fprintf(stderr, "sempose pattern: --center '%s' is not X,Y (pixels, e.g. 512,384)\n", center.c_str());
      return 2;
    }
  }
  {
    // A PGM written into the frames folder is read as a frame by the next replay or pattern
    // (a "size differs" failure), and one named like a frame overwrites the recording: the
    // pattern goes elsewhere.
    // Through a link too (resolved_output), and a hard link to a frame is that frame.
    std::error_code ec;
    if (cli::output_in_folder(out, dir)) {
      std::fprintf(stderr,
                   "sempose pattern: --out '%s' is in the frames folder %s: it would be read as a frame of the "
                   "recording%s; write the pattern outside it\n",
                   out.c_str(), dir.c_str(), std::filesystem::exists(out, ec) ? " (and overwrites one)" : "");
      return 2;
    }
    std::vector<cli::NamedPath> frames;
    cli::add_recording(frames, "--frames", dir);
    if (const std::string problem = cli::output_overwrites_input("--out", out, frames); !problem.empty()) {
      std::fprintf(stderr, "sempose pattern: %s\n", problem.c_str());
      return 2;
    }
  }
  try {
    const std::vector<std::string> names = hal::list_pgm_frames(dir);
    const std::size_t n = std::min<std::size_t>(names.size(), static_cast<std::size_t>(average));
    if (n < static_cast<std::size_t>(average)) {
      std::fprintf(stderr, "sempose pattern: warning: %s has %zu frames; averaging %zu, not %ld\n", dir.c_str(),
                   names.size(), n, average);
    }
    hal::Image first = hal::read_pgm(names[0]);
    const int w = first.width, h = first.height;
    const double half = (size - 1) / 2.0;
    const double x0 = cx - half, y0 = cy - half;
    if (size > w || size > h) {
      std::fprintf(stderr, "sempose pattern: --size %ld does not fit the %dx%d frames of %s (at most %d)\n", size, w, h,
                   dir.c_str(), std::min(w, h));
      return 2;
    }
    if (x0 < 0 || y0 < 0 || x0 + size - 1 > w - 1 || y0 + size - 1 > h - 1) {
      std::fprintf(stderr,
                   "sempose pattern: centre (%g, %g) is too close to the edge of the %dx%d frames for a %ld px "
                   "pattern (allowed x in [%g, %g], y in [%g, %g])\n",
                   cx, cy, w, h, size, half, w - 1 - half, half, h - 1 - half);
      return 2;
    }
    // The whole-pixel window the stillness check compares (the crop's pixels and their
    // bilinear neighbours).
    const int wx = static_cast<int>(std::floor(x0)), wy = static_cast<int>(std::floor(y0));
    const int wsize = static_cast<int>(std::min<long>(size + 1, std::min(w - wx, h - wy)));
    std::vector<double> mean(static_cast<std::size_t>(w) * h, 0.0);
    std::vector<double> window_mean(static_cast<std::size_t>(wsize) * wsize, 0.0);
    const double first_noise = cli::scan_noise_var(first, wx, wy, wsize);
    std::size_t used = 0;
    for (std::size_t f = 0; f < n; ++f) {
      if (const int sig = cli::stop_requested()) stopped_by(sig, f, n, out);
      const hal::Image img = f == 0 ? first : hal::read_pgm(names[f]);
      if (img.width != w || img.height != h) {
        std::fprintf(stderr, "sempose pattern: %s: size %dx%d differs from the first frame's %dx%d\n",
                     names[f].c_str(), img.width, img.height, w, h);
        return 2;
      }
      // A frame of another depth is from another recording (its grey levels mean other things).
      if (img.bits != first.bits) {
        std::fprintf(stderr, "sempose pattern: %s: %d-bit samples where the first frame has %d-bit ones\n",
                     names[f].c_str(), static_cast<int>(img.bits), static_cast<int>(first.bits));
        return 2;
      }
      if (f > 0) {
        const cli::StillnessCheck c = cli::check_stillness(window_mean, used, first_noise, img, wx, wy, wsize);
        if (!c.still) {
          std::fprintf(stderr,
                       "sempose pattern: warning: %s: the window around (%g, %g) changed against the %zu frame(s) "
                       "before it beyond their noise (ZNCC %.3f, a standing target: %.3f, at least %.3f): the target "
                       "moves or turns; averaging those %zu (record the pattern while it stands still)\n",
                       names[f].c_str(), cx, cy, used, c.zncc, c.expected, c.lowest, used);
          break;
        }
      }
      for (std::size_t i = 0; i < mean.size(); ++i) mean[i] += img.pixels[i];
      ++used;
      for (int y = 0; y < wsize; ++y) {
        for (int x = 0; x < wsize; ++x) {
          window_mean[static_cast<std::size_t>(y) * wsize + x] =
              mean[static_cast<std::size_t>(wy + y) * w + wx + x] / static_cast<double>(used);
        }
      }
    }
    for (auto& m : mean) m /= static_cast<double>(used);
    hal::Image pat;
    pat.width = pat.height = static_cast<std::int32_t>(size);
    pat.bits = first.bits;
    pat.pixels.resize(static_cast<std::size_t>(size) * size);
    const double maxv = first.bits > 8 ? 65535.0 : 255.0;
    // Frames of few grey levels (a PGM of maxval 1 or 3, a dim 8-bit scan): their mean's fractions
    // are what averaging gained, and rounding it back to those levels threw them away — the
    // pattern of a maxval-3 recording came out 0/1/2 and tracked nothing (found probing). The
    // mean is written stretched by a whole factor into the sample range; the tracker's
    // correlation does not see a gain, and the note says so.
    const double brightest = *std::max_element(mean.begin(), mean.end());
    const double stretch = brightest > 0 && brightest < maxv / 4 ? std::floor(maxv / std::ceil(brightest)) : 1.0;
    for (auto& m : mean) m *= stretch;
    if (stretch > 1) {
      std::printf("sempose pattern: the frames use grey levels up to %g only: the mean written x%g (%g of %g) to keep the "
                  "precision averaging gained\n", std::ceil(brightest), stretch, std::ceil(brightest) * stretch, maxv);
    }
    for (long y = 0; y < size; ++y) {
      for (long x = 0; x < size; ++x) {
        const double fx = x0 + x, fy = y0 + y;
        const int ix = std::min(static_cast<int>(fx), w - 2), iy = std::min(static_cast<int>(fy), h - 2);
        const double ax = fx - ix, ay = fy - iy;
        auto at = [&](int px, int py) { return mean[static_cast<std::size_t>(py) * w + px]; };
        const double v = (at(ix, iy) * (1 - ax) + at(ix + 1, iy) * ax) * (1 - ay) +
                         (at(ix, iy + 1) * (1 - ax) + at(ix + 1, iy + 1) * ax) * ay;
        pat.pixels[static_cast<std::size_t>(y) * size + x] = static_cast<std::uint16_t>(std::lround(std::min(maxv, v)));
      }
    }
    // A flat window (blank or saturated frames, the beam off) makes a pattern `run` and `replay`
    // refuse: it used to be written (exit 0) and refused only there, naming no frame.
    if (std::all_of(pat.pixels.begin(), pat.pixels.end(), [&](std::uint16_t v) { return v == pat.pixels[0]; })) {
      std::fprintf(stderr, "sempose pattern: the %ldx%ld window around (%g, %g) in %s is flat (every sample %u in the "
                   "mean of %zu frames): nothing to track there; %s not written\n",
                   size, size, cx, cy, dir.c_str(), static_cast<unsigned>(pat.pixels[0]), used, out.c_str());
      return 2;
    }
    if (const int sig = cli::stop_requested()) stopped_by(sig, used, n, out);
    try {
      hal::write_pgm(out, pat);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "sempose pattern: %s\n", cli::error_text(e).c_str());
      return 1;  // the output, not the input
    }
    // The pattern's own noise stays in every pose of a run (a fixed error no frame shows; README:
    // Uncertainty), so say how much is left: one scan's noise over √frames, against the
    // window's contrast (its variance less that noise).
    double sum = 0, sum2 = 0;
    for (const double v : window_mean) {
      sum += v;
      sum2 += v * v;
    }
    const double cells = static_cast<double>(window_mean.size());
    const double noise_var = first_noise / static_cast<double>(used);
    const double contrast_var = std::max(0.0, sum2 / cells - (sum / cells) * (sum / cells) - noise_var);
    std::printf("sempose pattern: %s: %ldx%ld around (%g, %g), mean of %zu frames; noise sigma %.2f grey levels (one "
                "scan's %.2f / sqrt %zu), contrast sigma %.2f: contrast-to-noise %.1f\n",
                out.c_str(), size, size, cx, cy, used, std::sqrt(noise_var), std::sqrt(first_noise), used,
                std::sqrt(contrast_var), noise_var > 0 ? std::sqrt(contrast_var / noise_var) : 0.0);
    // Said here, where the window is chosen (run and replay say it again at setup).
    const std::string rim = pose::rim_warning(
        pose::rim_information_share(pat.pixels.data(), pat.width, config::TrackerConfig{}.prefilter_passes));
    if (!rim.empty()) std::fprintf(stderr, "sempose pattern: warning: %s: %s\n", out.c_str(), rim.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sempose pattern: %s\n", cli::error_text(e).c_str());
    return 2;  // the frames: missing, unreadable, not PGM
  }
  return cli::report_lost("pattern") ? 4 : 0;
}
