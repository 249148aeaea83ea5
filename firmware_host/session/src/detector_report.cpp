#include "sempose/session/detector_report.hpp"

namespace sempose::session {

void print_detector_report(std::FILE* out, int t, const std::string& name, const pose::Tracker::DetectorTauStatus& d) {
  if (d.measuring)
    std::fprintf(out,
                 "detector %d %s: measured line_rho=%.3f lag2_excess=%+.3f tau_px=%.2f tau_ns=%.0f over %.0f ROI frames%s%s\n",
                 t, name.c_str(), d.rho, d.lag2_excess, d.tau_px, d.tau_ns, d.frames,
                 // Said only of a τ of 0: beside a measured lag it read as the measurement's verdict.
                 d.tau_px > 0 ? "" : " (0: a fast detector)",
                 d.inconsistent ? "; INCONSISTENT: the lines' correlation is not a detector low-pass's (rho2 != rho1^2: "
                                  "dropped lines?), no lag taken out"
                                : "");
  if (d.measuring && d.told_tau_ns > 0)
    std::fprintf(out, "detector %d %s: told tau_ns=%.0f: frames %s; pattern sets whose own noise overruled their dwell_ns: %d\n", t,
                 name.c_str(), d.told_tau_ns,
                 !d.frames_disagree ? "agree or not settled"
                 : d.frames_lag_measured
                     ? "DISAGREE (their measured lag used in place of the told one: check tracker.detector_tau_ns)"
                     : "DISAGREE (the told lag kept, the readings are no low-pass's: check tracker.detector_tau_ns and the scan)",
                 d.patterns_told_overruled);
  if (d.beyond_frames > 0)
    std::fprintf(out,
                 "detector %d %s: LAG BEYOND CORRECTION on %.0f frames: up to %.1f px between the frames' detector lag and the "
                 "pattern's, beyond the %.1f px sempose corrects; those poses UNCERTAIN (record the pattern at the tracking "
                 "dwell and give its dwell_ns, or scan slower)\n",
                 t, name.c_str(), d.beyond_frames, d.beyond_max_px, pose::Tracker::kMaxCorrectedLagPx);
}

}  // namespace sempose::session
