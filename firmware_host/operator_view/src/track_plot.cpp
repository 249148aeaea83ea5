#include "sempose/operator_view/track_plot.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "sempose/hal/cut_file.hpp"

namespace sempose::operator_view {
namespace {

// The largest angle order target's poses declare (1: its angle is absolute).
int order_of(const std::vector<PoseRow>& rows, const std::string& target) {
  int order = 1;
  for (const auto& r : rows) {
    if (r.target == target) order = std::max(order, r.angle_order);
  }
  return order;
}

// Text from outside (a target name read from the poses CSV, the file's name) as a gnuplot string:
// single-quoted, a quote doubled (gnuplot's only escape there) and any control character shown
// as '?'. A name holding "'; system('...')" was a command gnuplot ran, and a newline would end
// the string's line and start a command of its own (found probing `sempose view`).
std::string gnuplot_quoted(const std::string& text) {
  std::string out = "'";
  for (const char c : text) {
    if (c == '\'') out += "''";
    else out += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? '?' : c;
  }
  return out + "'";
}

// A path for the "run it by hand" message, quoted for a POSIX shell.
std::string shell_quoted(const std::string& path) {
  std::string out = "'";
  for (const char c : path) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// A plot 1000 px wide shows no more than a few thousand points a line; gnuplot's cairo took
// 28 s for 100k jumpy poses and over a minute for 200k (found probing; a 10 min run at 300
// poses/s is 180k). Above kPlotRows a target's poses are drawn in kPlotRows / 9 buckets, each
// by the rows holding its least and greatest x, y, phi and score and its first pose that was
// not TRACKING, in time order: every excursion and every lost stretch still shows.
constexpr std::size_t kPlotRows = 18000;

std::vector<const PoseRow*> rows_to_plot(const std::vector<const PoseRow*>& all) {
  if (all.size() <= kPlotRows) return all;
  const std::size_t buckets = kPlotRows / 9, per = (all.size() + buckets - 1) / buckets;
  std::vector<const PoseRow*> out;
  for (std::size_t b = 0; b < all.size(); b += per) {
    const std::size_t e = std::min(all.size(), b + per);
    std::vector<std::size_t> keep;
    auto extreme = [&](auto value) {
      std::size_t lo = b, hi = b;
      for (std::size_t i = b; i < e; ++i) {
        if (value(*all[i]) < value(*all[lo])) lo = i;
        if (value(*all[i]) > value(*all[hi])) hi = i;
      }
      keep.push_back(lo), keep.push_back(hi);
    };
    extreme([](const PoseRow& r) { return r.x_px; });
    extreme([](const PoseRow& r) { return r.y_px; });
    extreme([](const PoseRow& r) { return r.phi_deg; });
    extreme([](const PoseRow& r) { return r.score; });
    for (std::size_t i = b; i < e; ++i) {
      if (all[i]->status != "TRACKING") {
        keep.push_back(i);
        break;
      }
    }
    std::sort(keep.begin(), keep.end());
    keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
    for (std::size_t i : keep) out.push_back(all[i]);
  }
  return out;
}

}  // namespace

namespace {
// t − t0 in seconds; the 64-bit difference of two stamps far apart (any int64 is a valid t_ns)
// would overflow, so it is taken in doubles then (sub-µs resolution lost, a plot does not see it).
double seconds_since(std::int64_t t0, std::int64_t t) noexcept {
  std::int64_t d = 0;
  if (!__builtin_sub_overflow(t, t0, &d)) return static_cast<double>(d) * 1e-9;
  return (static_cast<double>(t) - static_cast<double>(t0)) * 1e-9;
}
}  // namespace

namespace {

// A PNG's last 12 bytes are its IEND chunk: length 0, "IEND", the CRC of "IEND".
bool png_is_whole(const std::string& path) {
  static constexpr unsigned char kIend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in || in.tellg() < static_cast<std::streamoff>(8 + sizeof kIend)) return false;
  in.seekg(-static_cast<std::streamoff>(sizeof kIend), std::ios::end);
  unsigned char tail[sizeof kIend] = {};
  in.read(reinterpret_cast<char*>(tail), sizeof tail);
  return in && std::equal(tail, tail + sizeof tail, kIend);
}

// gnuplot draws a view's few thousand points a line in 1-3 s (300,000 poses: 2.6 s); longer than
// this it is stuck (a font configuration that never loads: FONTCONFIG_FILE=/dev/zero hung it).
constexpr int kGnuplotSeconds = 20;

struct RunResult {
  int exec_errno = 0;      // why gnuplot could not be started (-1: its folder could not be entered)
  int status = 0;          // waitpid's status once it ran
  bool timed_out = false;  // stopped (SIGKILL) after the time limit
};

// gnuplot -d SCRIPT in `dir`, waited for at most `seconds`. The exec's own failure comes back
// through a close-on-exec pipe, so "not found" is told from a gnuplot that started and then
// failed (under `ulimit -v` its libraries did not load, exit 127, and view said "gnuplot not
// found" although it was installed; hostile round 10).
RunResult run_gnuplot(const std::string& dir, const std::string& script, int seconds) {
  RunResult r;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    r.exec_errno = errno;
    return r;
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    r.exec_errno = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    return r;
  }
  if (pid == 0) {
    int err = -1;
    if (::chdir(dir.c_str()) == 0) {
      ::execlp("gnuplot", "gnuplot", "-d", script.c_str(), static_cast<char*>(nullptr));
      err = errno;
    }
    [[maybe_unused]] const ssize_t n = ::write(fds[1], &err, sizeof err);
    ::_exit(127);
  }
  ::close(fds[1]);
  int err = 0;
  const ssize_t got = ::read(fds[0], &err, sizeof err);  // 0 bytes: the exec succeeded
  ::close(fds[0]);
  if (got == static_cast<ssize_t>(sizeof err)) r.exec_errno = err;
  for (int waited_ms = 0;; waited_ms += 20) {
    // (ECHILD: SIGCHLD ignored by whoever started sempose reaps the child itself; the picture's
    // own check after this tells whether it was drawn.)
    const pid_t done = ::waitpid(pid, &r.status, WNOHANG);
    if (done == pid || (done < 0 && errno != EINTR)) break;
    if (waited_ms >= seconds * 1000) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &r.status, 0);
      r.timed_out = r.exec_errno == 0;
      break;
    }
    ::usleep(20'000);
  }
  return r;
}

}  // namespace

std::string plot_track(const std::vector<PoseRow>& rows, const std::string& stem, const std::string& title) {
  const auto targets = targets_of(rows);
  const std::int64_t t0 = rows.front().t_ns;
  {
    // One gnuplot data block per target (separated by two blank lines: "index k").
    std::ofstream dat(stem + ".dat");
    // 12 significant digits: the stream's default 6 put an hour-long run's times 0.01 s apart
    // (a day's 0.1 s: frames of a 10 Hz stream on one abscissa).
    dat.precision(12);
    dat << "# t_s frame x_px y_px phi_deg score tracked(1/0)\n";
    for (const auto& t : targets) {
      std::vector<const PoseRow*> mine;
      for (const auto& r : rows) {
        if (r.target == t) mine.push_back(&r);
      }
      const std::vector<const PoseRow*> plotted = rows_to_plot(mine);
      dat << "# target " << (t.empty() ? "0" : t);
      if (plotted.size() < mine.size()) dat << " (" << plotted.size() << " of its " << mine.size() << " poses: each bucket's extremes)";
      dat << "\n";
      for (const PoseRow* r : plotted) {
        dat << seconds_since(t0, r->t_ns) << ' ' << r->frame << ' ' << r->x_px << ' ' << r->y_px << ' ' << r->phi_deg << ' '
            << r->score << ' ' << (r->status == "TRACKING" ? 1 : 0) << '\n';
      }
      dat << "\n\n";
    }
    dat.close();  // flushed here, so a full disk or a file-size limit shows (it was left cut, found probing)
    if (!dat) {
      throw std::runtime_error(stem + ".dat: cannot write (disk full or a file-size limit?); " +
                               hal::cut_file_outcome(hal::remove_cut_file(stem + ".dat")));
    }
  }
  // Recordings without timestamps (t_ns all 0) are plotted over the frame number.
  bool timed = false;
  for (const auto& r : rows) timed = timed || r.t_ns != t0;
  const std::string xcol = timed ? "1" : "2";
  // The script names its files by their leaf names and gnuplot runs in their folder: no path
  // from the command line is ever part of the script's text.
  const std::filesystem::path stem_path(stem);
  const std::string leaf = stem_path.filename().string();
  const std::string dir = stem_path.has_parent_path() ? stem_path.parent_path().string() : ".";
  {
    std::ofstream gp(stem + ".gp");
    gp << "set terminal pngcairo size 1000,900 font ',10'\n"
       << "set output " << gnuplot_quoted(leaf + ".png") << "\n"
       << "set multiplot layout 4,1 title " << gnuplot_quoted(title) << "\n"
       << "set grid\nset key outside right\nset lmargin 10\n";
    const char* panels[4][2] = {{"3", "x (px)"}, {"4", "y (px)"}, {"5", "phi (deg)"}, {"6", "score (ZNCC)"}};
    for (int p = 0; p < 4; ++p) {
      gp << "set ylabel '" << panels[p][1] << "'\n";
      gp << (p == 3 ? "set xlabel '" + std::string(timed ? "time (s)" : "frame") + "'\n" : "unset xlabel\n");
      gp << "plot ";
      for (std::size_t k = 0; k < targets.size(); ++k) {
        std::string name = targets[k].empty() ? "target 0" : "target " + targets[k];
        // A symmetric target's angle is known modulo 360°/n only: its phi line says so.
        if (p == 2 && order_of(rows, targets[k]) > 1) name += " (mod " + std::to_string(360 / order_of(rows, targets[k])) + ")";
        gp << (k ? ", " : "") << gnuplot_quoted(leaf + ".dat") << " index " << k << " using " << xcol << ":" << panels[p][0]
           << " with lines lw 1.2 title " << gnuplot_quoted(name);
        // Poses that were not TRACKING: marked on the line so lost stretches stand out.
        gp << ", '' index " << k << " using " << xcol << ":($7 == 0 ? $" << panels[p][0]
           << " : 1/0) with points pt 7 ps 0.4 lc rgb 'red' title '" << (k ? "" : "not TRACKING") << "'";
      }
      gp << "\n";
    }
    gp << "unset multiplot\n";
    gp.close();
    if (!gp) {
      throw std::runtime_error(stem + ".gp: cannot write (disk full or a file-size limit?); " +
                               hal::cut_file_outcome(hal::remove_cut_file(stem + ".gp")));
    }
  }
  // -d: the user's ~/.gnuplot is not read. It changed the picture view vouched for (`set datafile
  // missing "0"` dropped every not-TRACKING mark, exit 0), failed it unexplained (`set datafile
  // separator ","`) or hung it (`pause 3600`; hostile round 10).
  const std::string cmd = "cd " + shell_quoted(dir) + " && gnuplot -d " + shell_quoted(leaf + ".gp");
  // A picture gnuplot did not finish is no plot of this run (a blank panel, 0 bytes, or an
  // earlier view's): removed, said.
  const auto failed = [&](const std::string& why) {
    std::error_code ec;
    const bool removed = std::filesystem::remove(stem + ".png", ec);
    return why + (removed ? " (its unfinished " + leaf + ".png removed)" : "") + "; run: " + cmd;
  };
  const RunResult run = run_gnuplot(dir, leaf + ".gp", kGnuplotSeconds);
  if (run.exec_errno == ENOENT) return "gnuplot not found (apt-get install gnuplot-nox); then run: " + cmd;
  if (run.exec_errno == -1) return failed("cannot enter " + dir + " to run gnuplot");
  if (run.exec_errno != 0) return failed("cannot start gnuplot (" + std::string(std::strerror(run.exec_errno)) + ")");
  if (run.timed_out) return failed("gnuplot did not finish within " + std::to_string(kGnuplotSeconds) + " s and was stopped");
  if (!WIFEXITED(run.status) || WEXITSTATUS(run.status) != 0) {
    return failed("gnuplot failed on " + stem + ".gp (" +
                  (WIFEXITED(run.status) ? "exit status " + std::to_string(WEXITSTATUS(run.status))
                                         : "signal " + std::to_string(WTERMSIG(run.status))) +
                  ")");
  }
  // gnuplot exits 0 when its picture could not be written whole (a full disk, a file-size limit):
  // a PNG ends with its IEND chunk, or it was cut.
  if (!png_is_whole(stem + ".png")) {
    throw std::runtime_error(stem + ".png: gnuplot's picture is cut short (disk full or a file-size limit?); " +
                             hal::cut_file_outcome(hal::remove_cut_file(stem + ".png")));
  }
  return "";
}

}  // namespace sempose::operator_view
