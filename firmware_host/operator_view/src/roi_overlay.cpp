#include "sempose/operator_view/roi_overlay.hpp"

#include <algorithm>
#include <cmath>

namespace sempose::operator_view {

std::vector<std::pair<float, float>> pattern_edge_points(const hal::Image& p, double keep_fraction) {
  std::vector<std::pair<float, std::pair<float, float>>> mags;
  const double c = (p.width - 1) / 2.0, r = p.width / 2.0 - 1.5;
  for (int y = 1; y + 1 < p.height; ++y) {
    for (int x = 1; x + 1 < p.width; ++x) {
      const double u = x - c, v = y - (p.height - 1) / 2.0;
      if (u * u + v * v > r * r) continue;
      auto at = [&](int dx, int dy) { return static_cast<double>(p.at(x + dx, y + dy)); };
      const double gx = at(1, -1) + 2 * at(1, 0) + at(1, 1) - at(-1, -1) - 2 * at(-1, 0) - at(-1, 1);
      const double gy = at(-1, 1) + 2 * at(0, 1) + at(1, 1) - at(-1, -1) - 2 * at(0, -1) - at(1, -1);
      mags.push_back({static_cast<float>(std::hypot(gx, gy)), {static_cast<float>(u), static_cast<float>(v)}});
    }
  }
  const std::size_t keep = std::min(mags.size(), static_cast<std::size_t>(std::ceil(mags.size() * keep_fraction)));
  std::partial_sort(mags.begin(), mags.begin() + static_cast<std::ptrdiff_t>(keep), mags.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<std::pair<float, float>> out;
  for (std::size_t i = 0; i < keep; ++i) out.push_back(mags[i].second);
  return out;
}

RgbImage render_roi(const hal::Image& frame, const PoseRow& pose, int roi_px, int pattern_px,
                    const std::vector<std::pair<float, float>>& edges, int scale) {
  const int w = std::min(roi_px, frame.width), h = std::min(roi_px, frame.height);
  const int x0 = std::clamp(static_cast<int>(std::lround(pose.x_px)) - w / 2, 0, frame.width - w);
  const int y0 = std::clamp(static_cast<int>(std::lround(pose.y_px)) - h / 2, 0, frame.height - h);
  RgbImage img(w * scale, h * scale);
  const double full = frame.bits == 16 ? 65535.0 : 255.0;
  for (int y = 0; y < h * scale; ++y) {
    for (int x = 0; x < w * scale; ++x) {
      const auto g = static_cast<std::uint8_t>(std::lround(255.0 * frame.at(x0 + x / scale, y0 + y / scale) / full));
      img.pixels[static_cast<std::size_t>(y) * img.width + x] = Rgb{g, g, g};
    }
  }
  const Rgb colour = pose.status == "TRACKING" ? Rgb{40, 220, 60} : pose.status == "LOST" ? Rgb{235, 40, 40} : Rgb{240, 210, 30};
  const Rgb edge_colour{255, 0, 255};
  // Pattern offset (u, v) -> picture: X = c·u + s·v, Y = −s·u + c·v (CCW on screen), then scale.
  const double ph = pose.phi_deg * M_PI / 180.0, cs = std::cos(ph), sn = std::sin(ph);
  // Pixel i of the crop covers picture pixels i·scale … i·scale + scale − 1; its centre:
  const double cx = (pose.x_px - x0) * scale + (scale - 1) / 2.0, cy = (pose.y_px - y0) * scale + (scale - 1) / 2.0;
  auto to_pic = [&](double u, double v) { return std::pair<double, double>{cx + scale * (cs * u + sn * v), cy + scale * (-sn * u + cs * v)}; };
  const double half = pattern_px / 2.0;
  const std::pair<double, double> corners[4] = {to_pic(-half, -half), to_pic(half, -half), to_pic(half, half), to_pic(-half, half)};
  if (!std::isfinite(pose.x_px) || !std::isfinite(pose.y_px) || !std::isfinite(pose.phi_deg)) return img;
  for (const auto& e : edges) {
    const auto [px, py] = to_pic(e.first, e.second);
    img.plot(static_cast<int>(px), static_cast<int>(py), edge_colour);
  }
  for (int i = 0; i < 4; ++i) {
    img.line(corners[i].first, corners[i].second, corners[(i + 1) % 4].first, corners[(i + 1) % 4].second, colour);
  }
  img.circle(cx, cy, half * scale, colour);
  const auto tip = to_pic(half, 0);
  img.line(cx, cy, tip.first, tip.second, colour);
  img.line(cx - 4, cy, cx + 4, cy, colour);
  img.line(cx, cy - 4, cx, cy + 4, colour);
  return img;
}

}  // namespace sempose::operator_view
