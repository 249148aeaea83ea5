#include "sempose/pose/orientation_walk.hpp"

#include <algorithm>
#include <cmath>

#include "sempose/pose/score_cache.hpp"

namespace sempose::pose {

Measurement OrientationWalk::measure(const PatternBank& bank, int j, const Peak& pk, int max_moves) const noexcept {
  Measurement m;
  m.valid = true;
  m.psr = pk.psr;
  m.psr_valid = pk.psr_valid;
  int ux = 2 * pk.ux, uy = 2 * pk.uy;
  ScoreCache cache(scorer_, bank, angles_);
  auto score = [&](int jj, int x, int y) { return cache.score(jj, x, y); };
  // Position hill-climb at angle j (the binned peak is within a pixel or two).
  auto climb = [&](int jj) {
    for (int it = 0; it < 5; ++it) {
      int best = 4;
      float best_s = score(jj, ux, uy);
      for (int k = 0; k < 9; ++k) {
        const float sk = score(jj, ux + k % 3 - 1, uy + k / 3 - 1);
        if (sk > best_s) best_s = sk, best = k;
      }
      if (best == 4) return;
      ux += best % 3 - 1;
      uy += best / 3 - 1;
    }
  };
  climb(j);
  float s0 = score(j, ux, uy);
  float sm = score(j - 1, ux, uy);
  float sp = score(j + 1, ux, uy);
  int moves = 0;
  const int j_start = j;
  while (!(s0 >= sm && s0 >= sp)) {
    if (moves >= max_moves) {
      m.unsettled = true;
      break;
    }
    if (sp > sm) {
      sm = s0;
      s0 = sp;
      ++j;
      sp = score(j + 1, ux, uy);
    } else {
      sp = s0;
      s0 = sm;
      --j;
      sm = score(j - 1, ux, uy);
    }
    ++moves;
  }
  if (j != j_start) climb(j);  // the angle moved: the position's neighbourhood at the new angle
  // Joint fit; when its peak lies more than half a step away (a tie in the climb or the
  // walk), recentre on the nearest grid point once and fit again.
  bool fitted = false;
  for (int pass = 0; pass < 2; ++pass) {
    double dx = 0, dy = 0, dj = 0;
    bool plane = false;
    if (!fit_.fit_at(cache, ux, uy, j, dx, dy, dj, &plane)) break;
    fitted = true;
    m.background_plane = plane;
    m.dx = std::clamp(dx, -1.0, 1.0);
    m.dy = std::clamp(dy, -1.0, 1.0);
    m.dj = std::clamp(dj, -1.0, 1.0);
    if (pass == 1 || (std::fabs(dx) <= 0.6 && std::fabs(dy) <= 0.6 && std::fabs(dj) <= 0.6)) break;
    const int sx = static_cast<int>(std::lround(dx)), sy = static_cast<int>(std::lround(dy));
    const int sj = static_cast<int>(std::lround(dj));
    if (score(j + sj, ux + sx, uy + sy) < score(j, ux, uy)) break;
    ux += sx;
    uy += sy;
    j += sj;
    m.dx = std::clamp(dx - sx, -1.0, 1.0);
    m.dy = std::clamp(dy - sy, -1.0, 1.0);
    m.dj = std::clamp(dj - sj, -1.0, 1.0);
  }
  s0 = score(j, ux, uy);
  if (!fitted) {
    // No clear quadratic maximum (edge of the ROI, a ridge): separate 3-point fits.
    const bool gaussian = fit_.gaussian();
    const float l = score(j, ux - 1, uy), r = score(j, ux + 1, uy);
    const float up = score(j, ux, uy - 1), dn = score(j, ux, uy + 1);
    sm = score(j - 1, ux, uy);
    sp = score(j + 1, ux, uy);
    m.dx = (l > -2.0f && r > -2.0f) ? fit3(l, s0, r, gaussian) : 0.0;
    m.dy = (up > -2.0f && dn > -2.0f) ? fit3(up, s0, dn, gaussian) : 0.0;
    m.dj = (sm > -2.0f && sp > -2.0f) ? fit3(sm, s0, sp, false) : 0.0;
  }
  m.steps += cache.computed();
  // A place on the window's edge has no neighbour beyond it: the score there may still rise,
  // so the maximum is not confirmed (an ROI with no room around the pattern, or a target that
  // moved farther than the ROI's margin: found probing, TRACKING 6.6 px / 7° off).
  const int last_x = scorer_.roi_w() - bank.size_px(), last_y = scorer_.roi_h() - bank.size_px();
  m.on_window_edge = ux <= 0 || uy <= 0 || ux >= last_x || uy >= last_y;
  m.j = angles_.wrap(j);
  m.ux = ux;
  m.uy = uy;
  m.score = s0;
  return m;
}

}  // namespace sempose::pose
