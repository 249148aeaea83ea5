#include "sempose/config/refine_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {

void read_refine(Section& s, RefineConfig& c) {
  s.opt("enabled", c.enabled);
  s.opt("max_iterations", c.max_iterations, 1, 10);
  // Below a quarter pixel the fit could not correct the walk's own error (±0.5 px, ±0.5 step).
  s.opt("max_move_px", c.max_move_px, 0.25, 4.0);
  s.opt_choice("source", c.source, {"prefiltered", "raw"});
  s.opt("fit_scale", c.fit_scale);
  s.opt("fit_position", c.fit_position);
  s.opt("fit_angle", c.fit_angle);
  s.opt("min_score", c.min_score, 0.0, 1.0);
  s.opt("template_passes", c.template_passes, -1, 4);  // -1: auto
  s.opt("noise_weights", c.noise_weights);
  s.opt("black_level", c.black_level, 0.0, 0.5);
  s.opt("read_noise_counts", c.read_noise_counts, 0.0, 1.0e6);
}

}  // namespace sempose::config
