// The benchmark's check of the reported σ (issue 13 item 5): RMS(error / σ) per axis over a
// row's valid TRACKING poses (calibrated: 0.8–1.25), and pooled over groups of rows — the
// targets the calibration factor is fitted on (needle_tip, lamella_post) and the held-out ones
// (lamella, warped; the gripper's jaws apart: a deforming target), per dose — so that a factor is never judged on the rows it was
// fitted on — and over every row of a dose whatever its group (issue 13's own reading, "over the
// benchmark"). The per-row sums are over the poses the bench's RMS errors are over (TRACKING, not a
// start-search frame, ≤ 3 px and ≤ 10° off, not the frame of a jump).
#pragma once

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <utility>

namespace sempose::pose::testing {

struct ZSums {
  int n = 0, n_scale = 0;
  double x2 = 0, y2 = 0, phi2 = 0, scale2 = 0;
  double sigma_px = 0, sigma_deg = 0;  // sums of σ (for the mean σ printed beside)

  void add(double ex, double ey, double ephi, double escale, double sx, double sy, double sphi, double sscale) {
    if (!(sx > 0) || !(sy > 0) || !(sphi > 0)) return;
    ++n;
    x2 += (ex / sx) * (ex / sx);
    y2 += (ey / sy) * (ey / sy);
    phi2 += (ephi / sphi) * (ephi / sphi);
    sigma_px += std::hypot(sx, sy) / std::sqrt(2.0);
    sigma_deg += sphi;
    if (sscale > 0 && std::isfinite(escale)) {
      ++n_scale;
      scale2 += (escale / sscale) * (escale / sscale);
    }
  }
  void add(const ZSums& o) {
    n += o.n;
    n_scale += o.n_scale;
    x2 += o.x2;
    y2 += o.y2;
    phi2 += o.phi2;
    scale2 += o.scale2;
    sigma_px += o.sigma_px;
    sigma_deg += o.sigma_deg;
  }
  double zx() const { return n ? std::sqrt(x2 / n) : NAN; }
  double zy() const { return n ? std::sqrt(y2 / n) : NAN; }
  double zphi() const { return n ? std::sqrt(phi2 / n) : NAN; }
  double zscale() const { return n_scale ? std::sqrt(scale2 / n_scale) : NAN; }
  bool calibrated() const {
    auto in = [](double z) { return z >= 0.8 && z <= 1.25; };
    return n > 0 && in(zx()) && in(zy()) && in(zphi());
  }
};

// Which group a target's rows belong to.
inline bool sigma_fit_target(const std::string& target) { return target == "needle_tip" || target == "lamella_post"; }

// Pooled sums per (group, dose) and per row kind; prints the summary the README quotes.
class SigmaCalibrationTable {
 public:
  void add(const std::string& target, const std::string& label, double dose, const ZSums& z) {
    // The gripper's jaws deform the target under a rigid pattern: reported on their own.
    const int group = sigma_fit_target(target) ? 0 : target == "gripper" ? 2 : 1;
    groups_[{group, -dose}].add(z);
    all_[-dose].add(z);
    const bool special = label == "jaws" || label == "charge+defoc" || label.rfind("scale", 0) == 0;
    kinds_[special ? label : std::string("motion")].add(z);
    ++rows_;
    rows_in_range_ += z.calibrated();
    if (z.n > 0) ++rows_with_sigma_;
  }

  void print() const {
    if (!rows_) return;
    std::printf("\nsigma calibration: RMS(error/sigma) pooled over the valid TRACKING poses (target 0.8-1.25)\n");
    std::printf("%-34s %5s | %5s %5s %5s %6s | %8s %8s\n", "group", "dose", "z_x", "z_y", "z_phi", "z_scl", "sig_px", "sig_deg");
    for (const auto& [key, z] : groups_) {
      std::printf("%-34s %5.1f | %5.2f %5.2f %5.2f %6.2f | %8.4f %8.4f\n",
                  key.first == 0 ? "fit (needle_tip, lamella_post)" : key.first == 1 ? "held out (lamella, warped)" : "held out: gripper jaws", -key.second,
                  z.zx(), z.zy(), z.zphi(), z.zscale(), z.n ? z.sigma_px / z.n : NAN, z.n ? z.sigma_deg / z.n : NAN);
    }
    // Issue 13's own reading ("over the benchmark ... at doses 2.5-20"): every row of the dose,
    // whatever its group, the gripper's jaws included.
    for (const auto& [neg_dose, z] : all_) {
      std::printf("%-34s %5.1f | %5.2f %5.2f %5.2f %6.2f | %8.4f %8.4f\n", "all rows", -neg_dose, z.zx(), z.zy(), z.zphi(),
                  z.zscale(), z.n ? z.sigma_px / z.n : NAN, z.n ? z.sigma_deg / z.n : NAN);
    }
    for (const auto& [kind, z] : kinds_) {
      std::printf("%-34s %5s | %5.2f %5.2f %5.2f %6.2f | %8.4f %8.4f\n", ("rows: " + kind).c_str(), "all", z.zx(), z.zy(),
                  z.zphi(), z.zscale(), z.n ? z.sigma_px / z.n : NAN, z.n ? z.sigma_deg / z.n : NAN);
    }
    std::printf("rows with every axis's z in 0.8-1.25: %d of %d (with sigma)\n", rows_in_range_, rows_with_sigma_);
  }

 private:
  std::map<std::pair<int, double>, ZSums> groups_;
  std::map<std::string, ZSums> kinds_;
  std::map<double, ZSums> all_;  // by −dose (the highest first)
  int rows_ = 0, rows_in_range_ = 0, rows_with_sigma_ = 0;
};

}  // namespace sempose::pose::testing
