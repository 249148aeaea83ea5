#include "sempose/operator_view/track_plot.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <stdexcept>

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

}  // namespace

std::string plot_track(const std::vector<PoseRow>& rows, const std::string& stem, const std::string& title) {
  const auto targets = targets_of(rows);
  const std::int64_t t0 = rows.front().t_ns;
  {
    // One gnuplot data block per target (separated by two blank lines: "index k").
    std::ofstream dat(stem + ".dat");
    dat << "# t_s frame x_px y_px phi_deg score tracked(1/0)\n";
    for (const auto& t : targets) {
      dat << "# target " << (t.empty() ? "0" : t) << "\n";
      for (const auto& r : rows) {
        if (r.target != t) continue;
        dat << (r.t_ns - t0) * 1e-9 << ' ' << r.frame << ' ' << r.x_px << ' ' << r.y_px << ' ' << r.phi_deg << ' ' << r.score
            << ' ' << (r.status == "TRACKING" ? 1 : 0) << '\n';
      }
      dat << "\n\n";
    }
    if (!dat) throw std::runtime_error(stem + ".dat: cannot write");
  }
  // Recordings without timestamps (t_ns all 0) are plotted over the frame number.
  bool timed = false;
  for (const auto& r : rows) timed = timed || r.t_ns != t0;
  const std::string xcol = timed ? "1" : "2";
  {
    std::ofstream gp(stem + ".gp");
    gp << "set terminal pngcairo size 1000,900 font ',10'\n"
       << "set output '" << stem << ".png'\n"
       << "set multiplot layout 4,1 title '" << title << "'\n"
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
        gp << (k ? ", " : "") << "'" << stem << ".dat' index " << k << " using " << xcol << ":" << panels[p][0]
           << " with lines lw 1.2 title '" << name << "'";
        // Poses that were not TRACKING: marked on the line so lost stretches stand out.
        gp << ", '' index " << k << " using " << xcol << ":($7 == 0 ? $" << panels[p][0]
           << " : 1/0) with points pt 7 ps 0.4 lc rgb 'red' title '" << (k ? "" : "not TRACKING") << "'";
      }
      gp << "\n";
    }
    gp << "unset multiplot\n";
    if (!gp) throw std::runtime_error(stem + ".gp: cannot write");
  }
  const std::string cmd = "gnuplot '" + stem + ".gp'";
  const pid_t pid = fork();
  if (pid == 0) {
    execlp("gnuplot", "gnuplot", (stem + ".gp").c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) < 0) return "cannot start gnuplot; run: " + cmd;
  if (WIFEXITED(status) && WEXITSTATUS(status) == 127) return "gnuplot not found (apt-get install gnuplot-nox); then run: " + cmd;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return "gnuplot failed on " + stem + ".gp";
  return "";
}

}  // namespace sempose::operator_view
