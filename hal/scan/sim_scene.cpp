#include "sempose/hal/sim_scene.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "sempose/config/data_path.hpp"
#include "sempose/hal/pgm.hpp"
#include "sempose/hal/sim_rng.hpp"

namespace sempose::hal {

std::string resolve_data_path(const std::string& path, const std::string& what) {
  // A config read from a file already holds resolved paths; a config made in code (tests,
  // benchmarks) is looked up in the data folders only.
  std::string resolved, problem;
  if (!config::find_data_file(path, "", resolved, problem)) throw std::runtime_error(what + ": " + path + ": " + problem);
  return resolved;
}

void gaussian_blur(FloatImage& img, double sigma) {
  if (sigma <= 0.05 || img.w == 0 || img.h == 0) return;
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  std::vector<float> k(2 * r + 1);
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[i + r] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (auto& x : k) x = static_cast<float>(x / sum);
  std::vector<float> tmp(img.v.size());
  // Rows then columns; edges clamp (the scene continues beyond the field like its border).
  for (int y = 0; y < img.h; ++y) {
    const float* row = &img.v[static_cast<std::size_t>(y) * img.w];
    for (int x = 0; x < img.w; ++x) {
      float acc = 0;
      for (int i = -r; i <= r; ++i) acc += k[i + r] * row[std::clamp(x + i, 0, img.w - 1)];
      tmp[static_cast<std::size_t>(y) * img.w + x] = acc;
    }
  }
  for (int y = 0; y < img.h; ++y) {
    for (int x = 0; x < img.w; ++x) {
      float acc = 0;
      for (int i = -r; i <= r; ++i) acc += k[i + r] * tmp[static_cast<std::size_t>(std::clamp(y + i, 0, img.h - 1)) * img.w + x];
      img.v[static_cast<std::size_t>(y) * img.w + x] = acc;
    }
  }
}

FloatImage resample(const FloatImage& src, std::int32_t w, std::int32_t h) {
  if (src.w == w && src.h == h) return src;
  FloatImage out{w, h, std::vector<float>(static_cast<std::size_t>(w) * h)};
  const double sx = w > 1 ? (src.w - 1.0) / (w - 1.0) : 0.0;
  const double sy = h > 1 ? (src.h - 1.0) / (h - 1.0) : 0.0;
  for (int y = 0; y < h; ++y) {
    const double fy = y * sy;
    const int y0 = std::min(static_cast<int>(fy), src.h - 1), y1 = std::min(y0 + 1, src.h - 1);
    const double ay = fy - y0;
    for (int x = 0; x < w; ++x) {
      const double fx = x * sx;
      const int x0 = std::min(static_cast<int>(fx), src.w - 1), x1 = std::min(x0 + 1, src.w - 1);
      const double ax = fx - x0;
      const double top = src.at(x0, y0) * (1 - ax) + src.at(x1, y0) * ax;
      const double bot = src.at(x0, y1) * (1 - ax) + src.at(x1, y1) * ax;
      out.v[static_cast<std::size_t>(y) * w + x] = static_cast<float>(top * (1 - ay) + bot * ay);
    }
  }
  return out;
}

FloatImage crop_to_float(const Image& img, std::int32_t x, std::int32_t y, std::int32_t w, std::int32_t h,
                         const std::string& what) {
  if (w == 0 || h == 0) x = 0, y = 0, w = img.width, h = img.height;
  if (x < 0 || y < 0 || w <= 0 || h <= 0 || x + w > img.width || y + h > img.height) {
    throw std::runtime_error(what + ": crop [" + std::to_string(x) + ", " + std::to_string(y) + ", " +
                             std::to_string(w) + ", " + std::to_string(h) + "] is outside the " +
                             std::to_string(img.width) + "x" + std::to_string(img.height) + " image");
  }
  FloatImage out{w, h, std::vector<float>(static_cast<std::size_t>(w) * h)};
  const float scale = img.bits > 8 ? 1.0f / 65535.0f : 1.0f / 255.0f;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) out.v[static_cast<std::size_t>(j) * w + i] = img.at(x + i, y + j) * scale;
  }
  return out;
}

namespace {

// Keeps the largest 4-connected region of mask > 0.5 (the needle, not bright grains).
void keep_largest_region(FloatImage& m) {
  std::vector<int> label(m.v.size(), 0);
  std::vector<std::size_t> stack;
  int best_label = 0, next = 0;
  std::size_t best_size = 0;
  for (std::size_t s = 0; s < m.v.size(); ++s) {
    if (m.v[s] < 0.5f || label[s] != 0) continue;
    ++next;
    std::size_t size = 0;
    stack.push_back(s);
    label[s] = next;
    while (!stack.empty()) {
      const std::size_t p = stack.back();
      stack.pop_back();
      ++size;
      const int px = static_cast<int>(p % m.w), py = static_cast<int>(p / m.w);
      const int nx[4] = {px - 1, px + 1, px, px};
      const int ny[4] = {py, py, py - 1, py + 1};
      for (int k = 0; k < 4; ++k) {
        if (nx[k] < 0 || ny[k] < 0 || nx[k] >= m.w || ny[k] >= m.h) continue;
        const std::size_t q = static_cast<std::size_t>(ny[k]) * m.w + nx[k];
        if (m.v[q] >= 0.5f && label[q] == 0) {
          label[q] = next;
          stack.push_back(q);
        }
      }
    }
    if (size > best_size) best_size = size, best_label = next;
  }
  for (std::size_t s = 0; s < m.v.size(); ++s) m.v[s] = label[s] == best_label && best_label != 0 ? 1.0f : 0.0f;
}

FloatImage granular(std::int32_t w, std::int32_t h, double grain_px, std::uint64_t seed) {
  SimRng rng(seed, 0x6772616E);
  FloatImage n{w, h, std::vector<float>(static_cast<std::size_t>(w) * h)};
  for (auto& x : n.v) x = static_cast<float>(rng.normal());
  gaussian_blur(n, grain_px * 0.5);
  double sum = 0, sq = 0;
  for (float x : n.v) sum += x, sq += static_cast<double>(x) * x;
  const double mean = sum / n.v.size();
  const double sd = std::sqrt(std::max(1e-12, sq / n.v.size() - mean * mean));
  for (auto& x : n.v) x = static_cast<float>((x - mean) / sd);
  return n;
}

// Procedural shapes: alpha mask plus surface brightness with SEM edge brightening.
void procedural(const std::string& kind, std::int32_t w, std::int32_t h, std::uint64_t seed, FloatImage& tex,
                FloatImage& alpha) {
  alpha = FloatImage{w, h, std::vector<float>(static_cast<std::size_t>(w) * h, 0.0f)};
  auto fill = [&](double x0, double y0, double x1, double y1) {
    for (int y = static_cast<int>(y0 * h); y < static_cast<int>(y1 * h); ++y)
      for (int x = static_cast<int>(x0 * w); x < static_cast<int>(x1 * w); ++x)
        alpha.v[static_cast<std::size_t>(y) * w + x] = 1.0f;
  };
  double base = 0.6;
  if (kind == "gripper") {
    // Body on the left, two parallel jaws pointing to +x with a gap between them.
    fill(0.0, 0.08, 0.45, 0.92);
    fill(0.40, 0.12, 1.0, 0.36);
    fill(0.40, 0.64, 1.0, 0.88);
    base = 0.65;
  } else {  // lamella: a thin rectangular slab with a thicker frame on one side
    fill(0.0, 0.0, 1.0, 1.0);
    fill(0.0, 0.0, 0.15, 1.0);
    base = 0.55;
  }
  FloatImage grains = granular(w, h, 2.0, seed);
  FloatImage soft = alpha;
  gaussian_blur(soft, 1.5);
  tex = FloatImage{w, h, std::vector<float>(static_cast<std::size_t>(w) * h)};
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const auto i = static_cast<std::size_t>(y) * w + x;
      const float gx = soft.at(std::min(x + 1, w - 1), y) - soft.at(std::max(x - 1, 0), y);
      const float gy = soft.at(x, std::min(y + 1, h - 1)) - soft.at(x, std::max(y - 1, 0));
      const double edge = std::min(1.0, 2.5 * std::sqrt(gx * gx + gy * gy));
      tex.v[i] = static_cast<float>(std::clamp(base + 0.06 * grains.v[i] + 0.35 * edge, 0.0, 1.0));
    }
  }
}

SimLayer build_layer(const config::SimTargetConfig& t, std::size_t index, const config::SimConfig& cfg) {
  const std::string what = "sim.targets[" + std::to_string(index) + "].texture";
  FloatImage tex, alpha;
  if (t.texture.source == "image") {
    const std::string path = resolve_data_path(t.texture.path, what + ".path");
    Image img;
    std::string error;
    if (!try_read_pgm(path, img, error)) throw std::runtime_error(what + ": " + error);
    tex = crop_to_float(img, t.texture.crop_x, t.texture.crop_y, t.texture.crop_w, t.texture.crop_h, what);
    if (t.width_px > 0 && t.height_px > 0) tex = resample(tex, t.width_px, t.height_px);
    alpha = FloatImage{tex.w, tex.h, std::vector<float>(tex.v.size(), 1.0f)};
    if (t.texture.mask == "threshold") {
      FloatImage smooth = tex;
      gaussian_blur(smooth, 3.0);
      for (std::size_t i = 0; i < smooth.v.size(); ++i) alpha.v[i] = smooth.v[i] >= t.texture.mask_level ? 1.0f : 0.0f;
      keep_largest_region(alpha);
      double area = 0;
      for (float a : alpha.v) area += a;
      if (area < 16) {
        throw std::runtime_error(what + ": threshold mask at mask_level " + std::to_string(t.texture.mask_level) +
                                 " keeps nothing of the crop (lower mask_level or use mask: full)");
      }
    }
  } else {
    const std::int32_t w = t.width_px > 0 ? t.width_px : 128, h = t.height_px > 0 ? t.height_px : 96;
    procedural(t.texture.source, w, h, cfg.seed * 31 + index, tex, alpha);
  }
  // Pad so the PSF spreads beyond the mask edge, then premultiply and blur.
  const int pad = static_cast<int>(std::ceil(3.0 * cfg.psf_sigma_px)) + 2;
  SimLayer layer;
  layer.enabled = t.enabled;
  const std::int32_t w = tex.w + 2 * pad, h = tex.h + 2 * pad;
  layer.premul = FloatImage{w, h, std::vector<float>(static_cast<std::size_t>(w) * h, 0.0f)};
  layer.alpha = layer.premul;
  for (int y = 0; y < tex.h; ++y) {
    for (int x = 0; x < tex.w; ++x) {
      const auto s = static_cast<std::size_t>(y) * tex.w + x;
      const auto d = static_cast<std::size_t>(y + pad) * w + (x + pad);
      const float b = static_cast<float>(std::clamp(tex.v[s] * t.brightness, 0.0, 1.0));
      layer.alpha.v[d] = alpha.v[s];
      layer.premul.v[d] = b * alpha.v[s];
    }
  }
  gaussian_blur(layer.premul, cfg.psf_sigma_px);
  gaussian_blur(layer.alpha, cfg.psf_sigma_px);
  layer.cx = pad + (tex.w - 1) / 2.0;
  layer.cy = pad + (tex.h - 1) / 2.0;
  layer.radius = std::hypot(w / 2.0 + 1, h / 2.0 + 1);
  return layer;
}

}  // namespace

SimScene::SimScene(const config::SimConfig& cfg, const config::ScanLimits& limits) : cfg_(cfg) {
  if (cfg.targets.size() > 4) throw std::runtime_error("sim.targets: at most 4 targets");
  const std::int32_t fw = limits.field_w, fh = limits.field_h;
  const auto& bg = cfg.background;
  if (bg.source == "image") {
    const std::string path = resolve_data_path(bg.path, "sim.background.path");
    Image img;
    std::string error;
    if (!try_read_pgm(path, img, error)) throw std::runtime_error("sim.background: " + error);
    background_ = resample(crop_to_float(img, bg.crop_x, bg.crop_y, bg.crop_w, bg.crop_h, "sim.background"), fw, fh);
  } else {
    // Granular surface: fine grains plus a coarser undulation (a quarter of the contrast).
    background_ = granular(fw, fh, bg.grain_px, cfg.seed);
    const std::int32_t cw = fw / 32 + 2, ch = fh / 32 + 2;
    FloatImage coarse = granular(cw, ch, 1.0, cfg.seed + 7);
    FloatImage up = resample(coarse, fw + 64, fh + 64);
    for (int y = 0; y < fh; ++y) {
      for (int x = 0; x < fw; ++x) {
        const auto i = static_cast<std::size_t>(y) * fw + x;
        const double n = background_.v[i] + 0.5 * up.at(x, y);
        background_.v[i] = static_cast<float>(std::clamp(bg.mean + bg.contrast * n, 0.0, 1.0));
      }
    }
  }
  gaussian_blur(background_, cfg.psf_sigma_px);
  for (std::size_t i = 0; i < cfg.targets.size(); ++i) targets_.push_back(build_layer(cfg.targets[i], i, cfg));
}

}  // namespace sempose::hal
