#include "sempose/hal/sim_scene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
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

void gaussian_blur_in_place(float* img, int w, int h, double sigma, float* tmp) noexcept {
  if (sigma <= 0.05 || w <= 0 || h <= 0) return;
  sigma = std::min(sigma, kMaxBlurSigma);
  const int r = static_cast<int>(std::ceil(3.0 * sigma));
  std::array<float, 2 * 30 + 1> k{};
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[static_cast<std::size_t>(i + r)] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
  for (int i = 0; i <= 2 * r; ++i) k[static_cast<std::size_t>(i)] = static_cast<float>(k[static_cast<std::size_t>(i)] / sum);
  for (int y = 0; y < h; ++y) {
    const float* row = img + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      float acc = 0;
      for (int i = -r; i <= r; ++i) acc += k[static_cast<std::size_t>(i + r)] * row[std::clamp(x + i, 0, w - 1)];
      tmp[static_cast<std::size_t>(y) * w + x] = acc;
    }
  }
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float acc = 0;
      for (int i = -r; i <= r; ++i)
        acc += k[static_cast<std::size_t>(i + r)] * tmp[static_cast<std::size_t>(std::clamp(y + i, 0, h - 1)) * w + x];
      img[static_cast<std::size_t>(y) * w + x] = acc;
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

// Keeps the largest 4-connected region of mask > 0.5 (the needle, not bright grains); with
// `all`, every region of at least 5 % of the largest and 64 px too (a needle and the lamella it
// carries are two regions with a dark gap between them; grains stay out).
void keep_regions(FloatImage& m, bool all) {
  std::vector<int> label(m.v.size(), 0);
  std::vector<std::size_t> stack, sizes(1, 0);
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
    sizes.push_back(size);
    if (size > best_size) best_size = size, best_label = next;
  }
  const std::size_t min_size = std::max<std::size_t>(64, best_size / 20);
  for (std::size_t s = 0; s < m.v.size(); ++s) {
    const bool keep = label[s] != 0 && (label[s] == best_label || (all && sizes[static_cast<std::size_t>(label[s])] >= min_size));
    m.v[s] = keep ? 1.0f : 0.0f;
  }
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
    if (t.texture.mask == "threshold" || t.texture.mask == "threshold_all") {
      FloatImage smooth = tex;
      gaussian_blur(smooth, 3.0);
      for (std::size_t i = 0; i < smooth.v.size(); ++i) alpha.v[i] = smooth.v[i] >= t.texture.mask_level ? 1.0f : 0.0f;
      keep_regions(alpha, t.texture.mask == "threshold_all");
      double area = 0;
      for (float a : alpha.v) area += a;
      if (area < 16) {
        char level[32];
        std::snprintf(level, sizeof level, "%g", t.texture.mask_level);  // as written, not six decimals
        throw std::runtime_error(what + ": threshold mask at mask_level " + level +
                                 " keeps nothing of the crop (lower mask_level or use mask: full)");
      }
    }
  } else {
    const std::int32_t w = t.width_px > 0 ? t.width_px : 128, h = t.height_px > 0 ? t.height_px : 96;
    procedural(t.texture.source, w, h, cfg.seed * 31 + index, tex, alpha);
  }
  // Pad so the PSF spreads beyond the mask edge (and the jaws have room to open), then
  // premultiply and blur. A gripper whose jaws move is split into body and jaws: the jaws
  // are the parts right of 45 % of the width, above and below the middle.
  const bool jaws_move = t.texture.source == "gripper" && (!t.jaws.is_constant() || t.jaws.from != 0);
  const int pad = static_cast<int>(std::ceil(3.0 * cfg.psf_sigma_px)) + 2 +
                  (jaws_move ? static_cast<int>(std::ceil(t.jaws.max_abs())) : 0);
  SimLayer layer;
  layer.enabled = t.enabled;
  const std::int32_t w = tex.w + 2 * pad, h = tex.h + 2 * pad;
  const int n_parts = jaws_move ? 3 : 1;
  for (int part = 0; part < n_parts; ++part) {
    SimPart P;
    P.jaw_dir = part == 1 ? -1.0f : part == 2 ? 1.0f : 0.0f;
    P.premul = FloatImage{w, h, std::vector<float>(static_cast<std::size_t>(w) * h, 0.0f)};
    P.alpha = P.premul;
    for (int y = 0; y < tex.h; ++y) {
      for (int x = 0; x < tex.w; ++x) {
        if (jaws_move) {
          const bool jaw = x >= 0.45 * tex.w;
          const int which = !jaw ? 0 : y < tex.h / 2 ? 1 : 2;
          if (which != part) continue;
        }
        const auto s = static_cast<std::size_t>(y) * tex.w + x;
        const auto d = static_cast<std::size_t>(y + pad) * w + (x + pad);
        const float b = static_cast<float>(std::clamp(tex.v[s] * t.brightness, 0.0, 1.0));
        P.alpha.v[d] = alpha.v[s];
        P.premul.v[d] = b * alpha.v[s];
      }
    }
    gaussian_blur(P.premul, cfg.psf_sigma_px);
    gaussian_blur(P.alpha, cfg.psf_sigma_px);
    layer.parts.push_back(std::move(P));
  }
  layer.cx = pad + (tex.w - 1) / 2.0;
  layer.cy = pad + (tex.h - 1) / 2.0;
  layer.radius = std::hypot(w / 2.0 + 1, h / 2.0 + 1);
  return layer;
}

// Bilinear sample with the coordinates clamped to the image (the scene continues like its
// border beyond the field, e.g. under drift).
inline float sample_clamped(const FloatImage& img, float x, float y) noexcept {
  x = std::clamp(x, 0.0f, static_cast<float>(img.w - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.h - 1));
  const int x0 = std::min(static_cast<int>(x), img.w - 2 < 0 ? 0 : img.w - 2);
  const int y0 = std::min(static_cast<int>(y), img.h - 2 < 0 ? 0 : img.h - 2);
  const float ax = x - x0, ay = y - y0;
  const float* p = &img.v[static_cast<std::size_t>(y0) * img.w + x0];
  const float top = p[0] + ax * (p[1] - p[0]);
  const float bot = p[img.w] + ax * (p[img.w + 1] - p[img.w]);
  return top + ay * (bot - top);
}

constexpr double kDegToRad = 6.283185307179586 / 360.0;

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

LinePose SimScene::line_pose(std::size_t t, const SimTargetPose& p, float qy) const noexcept {
  LinePose lp;
  const SimLayer& L = targets_[t];
  if (!L.enabled || !p.active || !(p.scale > 0)) return lp;
  if (std::fabs(qy - p.y_px) > L.radius * (p.scale > 1.0 ? p.scale : 1.0)) return lp;
  // Inverse of the on-screen CCW rotation (README: Conventions) and of the scale: field -> texture.
  const double c = std::cos(p.phi_deg * kDegToRad), s = std::sin(p.phi_deg * kDegToRad);
  lp = {true, p.x_px, p.y_px, p.scale == 1.0 ? c : c / p.scale, p.scale == 1.0 ? s : s / p.scale,
        static_cast<float>(p.jaw_open_px)};
  return lp;
}

void SimScene::compose_line(const LinePose* poses, float qx0, float qy, const float* lag, int lag_n, int lag_offset,
                            int n, float* out, float* coverage) const noexcept {
  const std::size_t n_targets = targets_.size();
  for (int i = 0; i < n; ++i) {
    const int li = i + lag_offset;
    const float qx = qx0 + static_cast<float>(i) - (li >= 0 && li < lag_n ? lag[li] : 0.0f);
    float b = sample_clamped(background_, qx, qy);
    float cover = 0.0f;
    for (std::size_t t = 0; t < n_targets; ++t) {
      if (!poses[t].active) continue;
      const SimLayer& L = targets_[t];
      const float X = qx - static_cast<float>(poses[t].cx), Y = qy - static_cast<float>(poses[t].cy);
      const float c = static_cast<float>(poses[t].c), s = static_cast<float>(poses[t].s);
      const float u = static_cast<float>(L.cx) + c * X - s * Y;
      const float v_body = static_cast<float>(L.cy) + s * X + c * Y;
      for (const SimPart& part : L.parts) {
        // A jaw opened by o shows, at v, what its rest position shows at v ∓ o.
        const float v = part.jaw_dir == 0.0f ? v_body : v_body - part.jaw_dir * poses[t].jaw;
        const FloatImage& A_img = part.alpha;
        if (!(u >= 0.0f && v >= 0.0f && u < static_cast<float>(A_img.w - 1) && v < static_cast<float>(A_img.h - 1))) continue;
        const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
        const float au = u - u0, av = v - v0;
        const std::size_t o = static_cast<std::size_t>(v0) * A_img.w + u0;
        const float w00 = (1 - au) * (1 - av), w10 = au * (1 - av), w01 = (1 - au) * av, w11 = au * av;
        const float* A = &A_img.v[o];
        const float* P = &part.premul.v[o];
        const std::size_t st = static_cast<std::size_t>(A_img.w);
        const float a = w00 * A[0] + w10 * A[1] + w01 * A[st] + w11 * A[st + 1];
        const float pm = w00 * P[0] + w10 * P[1] + w01 * P[st] + w11 * P[st + 1];
        b = b * (1.0f - a) + pm;
        cover = std::max(cover, a);
      }
    }
    out[i] = b;
    if (coverage) coverage[i] = cover;
  }
}

void SimScene::render_mean(const Roi& roi, const SimTargetPose* poses, double gain, double offset, double defocus_px,
                           std::vector<float>& out, std::vector<float>* coverage) const {
  const double sigma = std::clamp(defocus_px, 0.0, kMaxBlurSigma);
  const int m = sigma > 0.05 ? static_cast<int>(std::ceil(3.0 * sigma)) : 0;
  const int W = roi.w + 2 * m, H = roi.h + 2 * m;
  std::vector<float> buf(static_cast<std::size_t>(W) * H), cov(coverage ? buf.size() : 0), tmp(m ? buf.size() : 0);
  std::vector<LinePose> lp(targets_.size());
  for (int r = 0; r < H; ++r) {
    const float qy = static_cast<float>(roi.y + r - m);
    for (std::size_t t = 0; t < targets_.size(); ++t) lp[t] = line_pose(t, poses[t], qy);
    compose_line(lp.data(), static_cast<float>(roi.x - m), qy, nullptr, 0, 0, W, &buf[static_cast<std::size_t>(r) * W],
                 coverage ? &cov[static_cast<std::size_t>(r) * W] : nullptr);
  }
  if (m) {
    gaussian_blur_in_place(buf.data(), W, H, sigma, tmp.data());
    if (coverage) gaussian_blur_in_place(cov.data(), W, H, sigma, tmp.data());
  }
  out.resize(static_cast<std::size_t>(roi.w) * roi.h);
  if (coverage) coverage->resize(out.size());
  for (int y = 0; y < roi.h; ++y)
    for (int x = 0; x < roi.w; ++x) {
      const std::size_t s = static_cast<std::size_t>(y + m) * W + (x + m), d = static_cast<std::size_t>(y) * roi.w + x;
      out[d] = static_cast<float>(std::max(0.0, buf[s] * gain + offset));
      if (coverage) (*coverage)[d] = cov[s];
    }
}

}  // namespace sempose::hal
