#include "sempose/pose/off_pose_score.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "sempose/pose/loss_policy.hpp"

namespace sempose::pose {
namespace {

// ZNCC of copy a against copy b displaced by (dx, dy) over their overlap (each copy zero
// outside its support; renormalised over the overlap, as a window would be).
double overlap_zncc(const float* a, const float* b, int n, int dx, int dy) noexcept {
  double ab = 0, aa = 0, bb = 0, sa = 0, sb = 0;
  long count = 0;
  for (int y = std::max(0, dy); y < std::min(n, n + dy); ++y)
    for (int x = std::max(0, dx); x < std::min(n, n + dx); ++x) {
      const double va = a[static_cast<long>(y) * n + x], vb = b[static_cast<long>(y - dy) * n + (x - dx)];
      if (va == 0 && vb == 0) continue;  // outside both supports
      ab += va * vb;
      aa += va * va;
      bb += vb * vb;
      sa += va;
      sb += vb;
      ++count;
    }
  if (count < 2) return 0;
  const double cov = ab - sa * sb / count, va = aa - sa * sa / count, vb = bb - sb * sb / count;
  return va > 0 && vb > 0 ? cov / std::sqrt(va * vb) : 0;
}

// The pattern's ZNCC against itself at each false-pose offset (the four shifts, then the turn;
// the turn -1 when the bank has one angle).
std::array<double, 5> off_pose_scores(const PatternBank& bank, double angle_step_deg) noexcept {
  const int n = bank.size_px();
  const float* p0 = bank.pattern(0);
  const int r = static_cast<int>(std::ceil(LossPolicy::kFalsePx));
  const int d = static_cast<int>(std::ceil(LossPolicy::kFalsePx / std::sqrt(2.0)));  // a diagonal step ≥ the radius
  std::array<double, 5> s{};
  int k = 0;
  for (const auto& o : {std::pair{r, 0}, std::pair{0, r}, std::pair{d, d}, std::pair{d, -d}})
    s[k++] = overlap_zncc(p0, p0, n, o.first, o.second);
  s[4] = -1;
  if (angle_step_deg > 0 && bank.angles() > 1) {
    const int j = std::min(bank.angles() - 1, static_cast<int>(std::ceil(LossPolicy::kFalseDeg / angle_step_deg - 1e-9)));
    s[4] = overlap_zncc(p0, bank.pattern(j), n, 0, 0);
  }
  return s;
}

}  // namespace

double off_pose_score(const PatternBank& bank, double angle_step_deg) noexcept {
  const auto s = off_pose_scores(bank, angle_step_deg);
  return std::clamp(*std::max_element(s.begin(), s.end()), 0.0, 1.0);
}

double nearest_off_pose_score(const PatternBank& bank, double angle_step_deg) noexcept {
  auto s = off_pose_scores(bank, angle_step_deg);
  if (s[4] < -0.5) s[4] = s[0];  // no turn measured: the shifts only
  return std::clamp(*std::min_element(s.begin(), s.end()), 0.0, 1.0);
}

}  // namespace sempose::pose
