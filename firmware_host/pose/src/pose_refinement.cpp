#include "sempose/pose/pose_refinement.hpp"

#include <cmath>

#include "sempose/rt/angle.hpp"

namespace sempose::pose {

bool PoseRefinement::add_set(const PatternBank& bank, const PatternImage& recorded) {
  const int P = bank.size_px();
  std::vector<std::uint8_t> inside(static_cast<std::size_t>(P) * P, 0);
  for (int k = 0; k < bank.support_band_count(0); ++k) {
    const MaskBand& b = bank.support_bands(0)[k];
    for (int y = b.y0; y <= b.y1; ++y)
      for (int x = b.x0; x <= b.x1; ++x) inside[static_cast<std::size_t>(y) * P + x] = 1;
  }
  std::vector<float> img(bank.pattern(0), bank.pattern(0) + static_cast<std::size_t>(P) * P);
  if (raw_ && recorded.width == P && recorded.height == P)
    for (std::size_t i = 0; i < img.size(); ++i) img[i] = static_cast<float>(recorded.pixels[i]);
  FitTemplate t;
  const bool ok = t.build(img.data(), P, inside.data());
  templates_.push_back(std::move(t));
  return ok;
}

Measurement PoseRefinement::refine(std::uint8_t set, const PatternBank& bank, const Measurement& m,
                                   const RawRoi& raw) const noexcept {
  Measurement out = m;
  if (!fit_.config().enabled || !m.valid || set >= templates_.size()) return out;
  out.refine_status = static_cast<std::uint8_t>(FitStatus::kSkipped);
  if (!(m.score >= fit_.config().min_score)) return out;
  const double c = (bank.size_px() - 1) / 2.0;
  const FitPose start{m.ux + m.dx + c, m.uy + m.dy + c, (m.j + m.dj) * step_deg_, 1.0};
  const FitTemplate& tpl = templates_[set];
  const FitResult r = raw_ ? fit_.fit(tpl, raw.px, scorer_.roi_w(), scorer_.roi_h(), raw.stride, start)
                           : fit_.fit(tpl, scorer_.roi(), scorer_.roi_w(), scorer_.roi_h(), scorer_.roi_w(), start);
  out.refine_status = static_cast<std::uint8_t>(r.status);
  if (r.status != FitStatus::kRefined) return out;
  if (fit_.config().fit_position) {
    out.dx = r.pose.cx - c - m.ux;
    out.dy = r.pose.cy - c - m.uy;
  }
  out.dj = rt::wrap_deg(r.pose.phi_deg - m.j * step_deg_) / step_deg_;
  out.refined_scale = static_cast<float>(r.pose.scale);
  return out;
}

std::size_t PoseRefinement::memory_bytes() const noexcept {
  std::size_t b = 0;
  for (const FitTemplate& t : templates_) b += t.memory_bytes();
  return b;
}

}  // namespace sempose::pose
