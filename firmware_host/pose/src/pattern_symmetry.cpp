#include "sempose/pose/pattern_symmetry.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/pattern_bank.hpp"

namespace sempose::pose {
namespace {

// Dot product of copy a with copy b displaced by (dx, dy): both zero-mean and unit norm over
// their supports, so ≈ the ZNCC a window showing b would give a (the part of b shifted out of
// a's square counts as a miss, as it would in a frame).
double shifted_dot(const float* a, const float* b, int n, int dx, int dy) noexcept {
  double dot = 0;
  for (int y = std::max(0, dy); y < std::min(n, n + dy); ++y) {
    const float* ra = a + static_cast<long>(y) * n;
    const float* rb = b + static_cast<long>(y - dy) * n;
    for (int x = std::max(0, dx); x < std::min(n, n + dx); ++x) dot += static_cast<double>(ra[x]) * rb[x - dx];
  }
  return dot;
}

struct BestShift {
  double score = -1;
  int dx = 0, dy = 0;
};

BestShift best_shift(const float* a, const float* b, int n, int reach) noexcept {
  BestShift best;
  for (int dy = -reach; dy <= reach; ++dy)
    for (int dx = -reach; dx <= reach; ++dx) {
      const double s = shifted_dot(a, b, n, dx, dy);
      if (s > best.score) best = {s, dx, dy};
    }
  return best;
}

}  // namespace

PatternSymmetry measure_symmetry(const PatternBank& bank, double same_look_score) {
  PatternSymmetry sym;
  sym.same_look_score = same_look_score;
  const int n = bank.size_px(), angles = bank.angles();
  if (angles < 2) return sym;
  const double step_deg = 360.0 / angles;
  const float* p0 = bank.pattern(0);
  const auto copy_turned_by = [&](double deg) { return bank.pattern(static_cast<int>(std::lround(deg / step_deg)) % angles); };
  std::array<BestShift, PatternSymmetry::kOrders.size()> best{};
  for (std::size_t i = 0; i < best.size(); ++i) {
    best[i] = best_shift(p0, copy_turned_by(360.0 / PatternSymmetry::kOrders[i]), n, PatternSymmetry::kNearShiftPx);
    sym.self_score[i] = best[i].score;
  }
  const auto same = [&](int order) {
    for (std::size_t i = 0; i < best.size(); ++i)
      if (order % PatternSymmetry::kOrders[i] == 0 &&
          !(sym.self_score[i] >= std::max(same_look_score, PatternSymmetry::kMinSameLookScore)))
        return false;
    return true;
  };
  for (std::size_t i = best.size(); i-- > 0;) {
    if (!same(PatternSymmetry::kOrders[i])) continue;
    sym.order = PatternSymmetry::kOrders[i];
    // The copy turned by θ about the pattern's centre matches at shift s when the pattern turns
    // onto itself about the centre c: s = (I − R(θ)) c, solved for c (y down: R's sign as the
    // bank turns its copies does not matter for n = 2, and the offset is a reading only).
    const double th = 2.0 * M_PI / sym.order, cs = std::cos(th), sn = std::sin(th);
    const double a = 1.0 - cs, b = sn, det = a * a + b * b;  // (I − R) = [[a, b], [−b, a]]
    sym.centre_dx_px = (a * best[i].dx - b * best[i].dy) / det;
    sym.centre_dy_px = (b * best[i].dx + a * best[i].dy) / det;
    break;
  }
  return sym;
}

}  // namespace sempose::pose
