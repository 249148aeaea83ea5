#include "sempose/pose/pattern_bank.hpp"

#include "sempose/pose/bicubic_rotate.hpp"
#include "sempose/pose/box_downsample.hpp"
#include "sempose/pose/prefilter.hpp"
#include "sempose/pose/window_noise.hpp"
#include "sempose/rt/memory_room.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <new>
#include <random>
#include <string>
#include <vector>

namespace sempose::pose {

void FftwFree::operator()(void* p) const noexcept { fftwf_free(p); }

namespace {
std::string megabytes(std::uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.0f MB", static_cast<double>(bytes) / 1e6);
  return text;
}
}  // namespace

void downsample_pattern(const float* src, int n, int factor, float* out) noexcept {
  const int m = n / factor;
  const int off = (n - m * factor) / 2;
  box_downsample<float, double, float>(src, n, off, off, factor, m, m, out);
}

std::unique_ptr<const PatternBank> PatternBank::build(const PatternBankSpec& spec, const BankLevels& levels,
                                                     std::string& why) {
  std::unique_ptr<PatternBank> bank(new PatternBank());
  if (!bank->fill(spec, levels, why)) return nullptr;
  return bank;
}

bool PatternBank::fill(const PatternBankSpec& spec, const BankLevels& levels, std::string& why) {
  const PatternImage& pattern = spec.pattern;
  const PatternImage& shape_image = spec.shape;
  const PatternMask& fine_mask = levels.fine_mask;
  const PatternMask& half_mask = levels.half_mask;
  const PatternMask& coarse_mask = levels.coarse_mask;
  FftCorrelator& half = levels.half;
  FftCorrelator& coarse = levels.coarse;
  const double step_deg = spec.angle_step_deg, coarse_step_deg = spec.coarse_step_deg;
  const int factor = spec.coarse_factor;
  size_ = pattern.width;
  const int n = size_;
  angles_ = static_cast<int>(std::lround(360.0 / step_deg));
  coarse_step_deg_ = coarse_step_deg;
  coarse_angles_ = std::max(1, static_cast<int>(std::lround(360.0 / coarse_step_deg)));
  spectrum_len_ = half.spectrum_len();
  const int h = half_mask.size_px();
  std::vector<float> halved(static_cast<std::size_t>(h) * h);
  coarse_len_ = coarse.spectrum_len();
  FftCorrelator* coarse_wide = levels.coarse_wide;
  coarse_wide_len_ = coarse_wide ? coarse_wide->spectrum_len() : 0;
  const int m = coarse_mask.size_px();

  std::vector<float> src(static_cast<std::size_t>(n) * n), raw(src.size()), small(static_cast<std::size_t>(m) * m);
  for (std::size_t i = 0; i < src.size(); ++i) src[i] = static_cast<float>(pattern.pixels[i]);
  const auto [lo, hi] = std::minmax_element(src.begin(), src.end());
  // Detail only at the pixel scale (a 1-px checkerboard) is averaged away by the prefilter's
  // binomial kernel or the 2×2 bins of the search: refused as such, not as a flat pattern.
  const char* no_contrast = *lo == *hi ? "the pattern is flat (constant grey level) inside its mask"
                                       : "the pattern has no contrast the tracker can use inside its mask: detail "
                                         "only at the pixel scale (e.g. a 1-px checkerboard) is averaged away by the "
                                         "prefilter (tracker.prefilter_passes) and the 2x2 binned search level";
  // The frame is low-passed the same way (Prefilter); filtering before rotating is the same
  // as after for this near-isotropic kernel and keeps one interpolation for all angles.
  prefilter_pattern(src.data(), n, spec.prefilter_passes);
  // A config inside every key's range can still ask for more than the machine has (found
  // probing: pattern 512, ROI 1024, 0.25° steps at full resolution: tens of GB, and setup
  // ended in "out of memory" naming nothing, or in the OOM killer). Said with its parts.
  const std::uint64_t copies = static_cast<std::uint64_t>(angles_) * n * n * sizeof(float);
  const std::uint64_t fine = sizeof(Complex) * static_cast<std::uint64_t>(spectrum_len_) * angles_;
  const std::uint64_t search = sizeof(Complex) * static_cast<std::uint64_t>(coarse_len_ + coarse_wide_len_) * coarse_angles_;
  if (const std::uint64_t avail = rt::memory_room().least(); avail > 0 && copies + fine + search > avail) {
    why = "the pattern bank needs " + megabytes(copies + fine + search) + ", more than the " + megabytes(avail) +
          " this machine has available: " + std::to_string(angles_) + " turned copies of the " + std::to_string(n) + "² pattern " +
          megabytes(copies) + " (tracker.angle_step_deg, tracker.pattern_size_px), their spectra at the ROI's size " +
          megabytes(fine) + " (tracker.roi_size_px), " + std::to_string(coarse_angles_) + " start-search spectra " +
          megabytes(search) + " (tracker.search_angle_step_deg, tracker.search_downsample, the field's size)";
    return false;
  }
  spatial_.assign(static_cast<std::size_t>(angles_) * n * n, 0.0f);
  spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * spectrum_len_ * angles_)), FftwFree{});
  coarse_spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * coarse_len_ * coarse_angles_)), FftwFree{});
  if (coarse_wide)
    coarse_wide_spectra_.reset(static_cast<Complex*>(fftwf_malloc(sizeof(Complex) * coarse_wide_len_ * coarse_angles_)),
                               FftwFree{});
  if (!spectra_ || !coarse_spectra_ || (coarse_wide && !coarse_wide_spectra_)) throw std::bad_alloc();

  has_shape_ = !shape_image.empty();
  std::vector<float> shape(src.size(), 1.0f), shape_scratch(src.size());
  if (has_shape_) {
    if (shape_image.width != n || shape_image.height != n) {
      why = "the shape mask is " + std::to_string(shape_image.width) + "x" + std::to_string(shape_image.height) +
            ", the pattern " + std::to_string(n) + "x" + std::to_string(n) + "; they must be the same size";
      return false;
    }
    for (std::size_t i = 0; i < shape.size(); ++i) shape[i] = shape_image.pixels[i] != 0 ? 1.0f : 0.0f;
    dilate_disk(shape, n, spec.shape_margin_px);
  }
  std::vector<std::uint8_t> fine_in(src.size());
  std::vector<double> norm(static_cast<std::size_t>(angles_), 0.0);  // copy = (turned − mean) · norm[j]
  support_.clear();
  support_begin_.assign(1, 0);
  support_count_.clear();
  for (int j = 0; j < angles_; ++j) {
    float* p = spatial_.data() + static_cast<std::size_t>(j) * n * n;
    rotate_pattern(src.data(), n, j * step_deg, raw.data());
    std::copy(raw.begin(), raw.end(), p);
    downsample_pattern(raw.data(), n, 2, halved.data());
    // The shape mask applies to the exact full-resolution scores (the fit); the binned and
    // coarse levels that only locate the peak keep the whole circle: a silhouette's outline
    // at ×2 or ×8 is too thin a support to find it reliably (measured: the needle was
    // acquired elsewhere at margins below 6 px).
    std::int64_t count = fine_mask.count();
    if (has_shape_) {
      count = turned_support(shape, n, j * step_deg, fine_mask.bitmap(), shape_scratch, fine_in);
    } else {
      std::copy_n(fine_mask.bitmap(), fine_in.size(), fine_in.begin());
    }
    {
      double sum = 0, ss = 0, cnt = 0;
      for (std::size_t i = 0; i < fine_in.size(); ++i)
        if (fine_in[i]) {
          sum += p[i];
          cnt += 1;
        }
      const double mean = cnt > 0 ? sum / cnt : 0.0;
      for (std::size_t i = 0; i < fine_in.size(); ++i)
        if (fine_in[i]) ss += (p[i] - mean) * (p[i] - mean);
      norm[static_cast<std::size_t>(j)] = ss > 0 ? 1.0 / std::sqrt(ss) : 0.0;
    }
    if (!normalize_pattern(p, n, fine_in.data()) || !normalize_pattern(halved.data(), half_mask)) {
      why = has_shape_ && count < 64 ? "the shape mask leaves under 64 pixels inside the pattern circle" : no_contrast;
      return false;
    }
    const std::vector<MaskBand> bands = has_shape_ ? bands_of(fine_in.data(), n) : fine_mask.bands();
    support_.insert(support_.end(), bands.begin(), bands.end());
    support_begin_.push_back(support_.size());
    support_count_.push_back(count);
    half.make_spectrum(halved.data(), spectra_.get() + static_cast<std::size_t>(j) * spectrum_len_);
  }
  for (int k = 0; k < coarse_angles_; ++k) {
    rotate_pattern(src.data(), n, k * coarse_step_deg, raw.data());
    downsample_pattern(raw.data(), n, factor, small.data());
    if (!normalize_pattern(small.data(), coarse_mask)) {
      why = "the pattern is flat after downsampling by search_downsample";
      return false;
    }
    coarse.make_spectrum(small.data(), coarse_spectra_.get() + static_cast<std::size_t>(k) * coarse_len_);
    if (coarse_wide)
      coarse_wide->make_spectrum(small.data(), coarse_wide_spectra_.get() + static_cast<std::size_t>(k) * coarse_wide_len_);
  }
  model_pattern_noise(pattern, spec.prefilter_passes, norm);
  measure_plane_grams();
  return true;
}

void PatternBank::measure_plane_grams() {
  const int n = size_;
  const double c = (n - 1) / 2.0;
  plane_gram_.assign(static_cast<std::size_t>(angles_), PlaneGram{});
  for (int j = 0; j < angles_; ++j) {
    const float* t = pattern(j);
    double sum[3] = {}, cross[3][3] = {};
    for (int k = 0; k < support_band_count(j); ++k) {
      const MaskBand& b = support_bands(j)[k];
      for (int y = b.y0; y <= b.y1; ++y)
        for (int x = b.x0; x <= b.x1; ++x) {
          const double r[3] = {t[static_cast<std::size_t>(y) * n + x], (x - c) / n, (y - c) / n};
          for (int p = 0; p < 3; ++p) {
            sum[p] += r[p];
            for (int q = 0; q < 3; ++q) cross[p][q] += r[p] * r[q];
          }
        }
    }
    const double count = static_cast<double>(support_count(j));
    PlaneGram& pg = plane_gram_[static_cast<std::size_t>(j)];
    const double mean[3] = {sum[0] / count, sum[1] / count, sum[2] / count};
    pg.mean_x = mean[1];
    pg.mean_y = mean[2];
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) pg.g[p][q] = cross[p][q] - count * mean[p] * mean[q];
    pg.factored = true;
    for (int i = 0; i < 3 && pg.factored; ++i)
      for (int k = 0; k <= i; ++k) {
        double v = pg.g[i][k];
        for (int m = 0; m < k; ++m) v -= pg.chol[i][m] * pg.chol[k][m];
        if (i != k) {
          pg.chol[i][k] = v / pg.chol[k][k];
        } else if (v > 1e-12 * pg.g[i][i]) {
          pg.chol[i][i] = std::sqrt(v);
        } else {
          pg.factored = false;
          break;
        }
      }
  }
}

bool PatternBank::PlaneGram::whiten(const double b[3], double w[3]) const noexcept {
  if (!factored) return false;
  for (int i = 0; i < 3; ++i) {
    double v = b[i];
    for (int m = 0; m < i; ++m) v -= chol[i][m] * w[m];
    w[i] = v / chol[i][i];
  }
  return true;
}

bool PatternBank::PlaneGram::solve(const double b[3], double z[3]) const noexcept {
  double w[3];
  if (!whiten(b, w)) return false;
  for (int i = 2; i >= 0; --i) {
    double v = w[i];
    for (int m = i + 1; m < 3; ++m) v -= chol[m][i] * z[m];
    z[i] = v / chol[i][i];
  }
  return true;
}

void PatternBank::model_pattern_noise(const PatternImage& pattern, int prefilter_passes, const std::vector<double>& norm) {
  const int n = size_;
  noise_gram_.clear();
  const WindowNoise wn = line_correlated_noise(pattern.pixels.data(), n, 0, 0, n);
  pattern_noise_var_ = wn.var;
  pattern_noise_rho_ = wn.rho;
  if (!(wn.var > 0)) return;
  // One noise field of the measured variance and line correlation (AR(1) along x), fixed seed
  // (setup is deterministic), through the pattern's own prefilter.
  std::vector<float> field(static_cast<std::size_t>(n) * n);
  std::mt19937 rng(0x5e4d05e);
  std::normal_distribution<double> white(0.0, 1.0);
  const double rho = wn.rho, innov = std::sqrt(std::max(0.0, 1.0 - rho * rho)), sd = std::sqrt(wn.var);
  for (int y = 0; y < n; ++y) {
    double v = white(rng);
    for (int x = 0; x < n; ++x) {
      if (x > 0) v = rho * v + innov * white(rng);
      field[static_cast<std::size_t>(y) * n + x] = static_cast<float>(sd * v);
    }
  }
  prefilter_pattern(field.data(), n, prefilter_passes);
  // Angle k's noise copy as the σ stage sees the bank's copy: turned, inside k's support,
  // scaled like the copy (the support mean the copy loses is ~1/√support of the noise: left in).
  const std::size_t nn = static_cast<std::size_t>(n) * n;
  auto copy_of = [&](int k, std::vector<float>& out, std::vector<std::uint8_t>& in) {
    k = ((k % angles_) + angles_) % angles_;
    rotate_pattern(field.data(), n, k * (360.0 / angles_), out.data());
    std::fill(in.begin(), in.end(), std::uint8_t{0});
    for (std::size_t b = support_begin_[static_cast<std::size_t>(k)]; b < support_begin_[static_cast<std::size_t>(k) + 1]; ++b) {
      const MaskBand& band = support_[b];
      for (int y = band.y0; y <= band.y1; ++y)
        for (int x = band.x0; x <= band.x1; ++x) in[static_cast<std::size_t>(y) * n + x] = 1;
    }
    const float s = static_cast<float>(norm[static_cast<std::size_t>(k)]);
    for (std::size_t i = 0; i < nn; ++i) out[i] = in[i] ? out[i] * s : 0.0f;
  };
  std::vector<float> copies[3] = {std::vector<float>(nn), std::vector<float>(nn), std::vector<float>(nn)};
  std::vector<std::uint8_t> ins[3] = {std::vector<std::uint8_t>(nn), std::vector<std::uint8_t>(nn), std::vector<std::uint8_t>(nn)};
  copy_of(-1, copies[0], ins[0]);
  copy_of(0, copies[1], ins[1]);
  constexpr int K = kNoiseParams;
  noise_gram_.assign(static_cast<std::size_t>(angles_) * K * K, 0.0);
  const double step_deg = 360.0 / angles_;
  const double per_deg = 0.5 / step_deg, c = 0.5 * (n - 1);
  std::vector<double> gx(static_cast<std::size_t>(n));
  for (int j = 0; j < angles_; ++j) {
    // Ring of three: j − 1, j, j + 1.
    const int im = (j + 2) % 3, ic = j % 3, ip = (j + 1) % 3;
    if (j == 0) {
      // copies[0] holds −1 and copies[1] holds 0: move them to the ring's slots for j = 0 (im = 2, ic = 0).
      std::swap(copies[2], copies[0]);
      std::swap(ins[2], ins[0]);
      std::swap(copies[0], copies[1]);
      std::swap(ins[0], ins[1]);
    }
    copy_of(j + 1, copies[ip], ins[ip]);
    const float* t = copies[ic].data();
    const std::uint8_t* in = ins[ic].data();
    const float* tp = copies[ip].data();
    const float* tm = copies[im].data();
    double g[K][K] = {};
    double tan2 = 0;  // the φ column's noise energy as the tangential derivative of copy j
    for (std::size_t b = support_begin_[static_cast<std::size_t>(j)]; b < support_begin_[static_cast<std::size_t>(j) + 1]; ++b) {
      const MaskBand& band = support_[b];
      for (int v = band.y0; v <= band.y1; ++v) {
        const float* row = t + static_cast<std::size_t>(v) * n;
        const int x0 = band.x0, x1 = band.x1;
        // The σ stage's columns (pose_uncertainty.cpp, row_terms), on the noise copy.
        for (int u = x0; u <= x1; ++u)
          gx[static_cast<std::size_t>(u)] = x1 == x0 ? 0.0
                                             : u == x0 ? row[u + 1] - row[u]
                                             : u == x1 ? row[u] - row[u - 1]
                                                       : 0.5 * (row[u + 1] - row[u - 1]);
        for (int u = x0; u <= x1; ++u) {
          const std::size_t i = static_cast<std::size_t>(v) * n + u;
          const bool up = v > 0 && in[i - n], dn = v + 1 < n && in[i + n];
          const double tc = t[i], tu = up ? t[i - n] : tc, td = dn ? t[i + n] : tc;
          double a[K];
          a[0] = gx[static_cast<std::size_t>(u)];
          a[1] = (up && dn ? 0.5 : 1.0) * (td - tu);
          a[2] = per_deg * (tp[i] - tm[i]);
          const double tangential = (M_PI / 180.0) * ((u - c) * a[1] - (v - c) * a[0]);
          tan2 += tangential * tangential;
          a[3] = (u - c) * a[0] + (v - c) * a[1];
          a[4] = tc;
          a[5] = 0.0;
          for (int p = 0; p < K - 1; ++p)
            for (int q = 0; q < K - 1; ++q) g[p][q] += a[p] * a[q];
        }
      }
    }
    // The φ column: the bank's neighbour difference (what J holds) over-states what the walk's
    // angle fit feels of the noise, the tangential derivative of one copy under-states it
    // (pose_uncertainty_test, noisy pattern: 1.6× too large / 1.4–2.4× too small a σφ); the
    // geometric mean of the two energies, the φ row and column scaled alike.
    if (g[2][2] > 0 && tan2 > 0) {
      const double f = std::sqrt(std::sqrt(tan2 / g[2][2]));
      for (int p = 0; p < K; ++p) {
        g[2][p] *= f;
        g[p][2] *= f;
      }
    }
    double* out = noise_gram_.data() + static_cast<std::size_t>(j) * K * K;
    for (int p = 0; p < K; ++p)
      for (int q = 0; q < K; ++q) out[p * K + q] = g[p][q];
  }
}

std::unique_ptr<const PatternBank> PatternBank::with_support(const PatternBank& base,
                                                            const std::vector<std::uint8_t>& support, std::string& why,
                                                            const float* refined, double noise_factor) {
  const int n = base.size_;
  if (support.size() != static_cast<std::size_t>(n) * n) {
    why = "the support is not pattern-sized";
    return nullptr;
  }
  std::unique_ptr<PatternBank> bank(new PatternBank());
  PatternBank& b = *bank;
  b.size_ = n;
  b.angles_ = base.angles_;
  b.coarse_angles_ = base.coarse_angles_;
  b.coarse_step_deg_ = base.coarse_step_deg_;
  b.spectrum_len_ = base.spectrum_len_;
  b.coarse_len_ = base.coarse_len_;
  b.coarse_wide_len_ = base.coarse_wide_len_;
  b.spectra_ = base.spectra_;
  b.coarse_spectra_ = base.coarse_spectra_;
  b.coarse_wide_spectra_ = base.coarse_wide_spectra_;
  b.has_shape_ = true;
  b.spatial_ = base.spatial_;
  b.support_begin_.assign(1, 0);
  const double c = (n - 1) / 2.0;
  const double step_deg = 360.0 / b.angles_;
  std::vector<std::uint8_t> in(support.size());
  for (int j = 0; j < b.angles_; ++j) {
    // Angle j's copy shows source offset M·d at output offset d (bicubic_rotate's map).
    const double rad = j * step_deg * M_PI / 180.0, cs = std::cos(rad), sn = std::sin(rad);
    std::fill(in.begin(), in.end(), 0);
    for (int k = base.support_begin_[j]; k < static_cast<int>(base.support_begin_[j + 1]); ++k) {
      const MaskBand& band = base.support_[static_cast<std::size_t>(k)];
      for (int y = band.y0; y <= band.y1; ++y)
        for (int x = band.x0; x <= band.x1; ++x) {
          const double dx = x - c, dy = y - c;
          const int sx = static_cast<int>(std::lround(c + dx * cs - dy * sn));
          const int sy = static_cast<int>(std::lround(c + dx * sn + dy * cs));
          if (sx >= 0 && sy >= 0 && sx < n && sy < n && support[static_cast<std::size_t>(sy) * n + sx])
            in[static_cast<std::size_t>(y) * n + x] = 1;
        }
    }
    std::int64_t count = 0;
    for (std::uint8_t v : in) count += v;
    float* p = b.spatial_.data() + static_cast<std::size_t>(j) * n * n;
    double renorm = 0;  // the renormalisation's factor on base's copy
    {
      double sum = 0, ss = 0;
      for (std::size_t i = 0; i < in.size(); ++i)
        if (in[i]) sum += p[i];
      const double mean = count > 0 ? sum / static_cast<double>(count) : 0.0;
      for (std::size_t i = 0; i < in.size(); ++i)
        if (in[i]) ss += (p[i] - mean) * (p[i] - mean);
      renorm = ss > 0 ? 1.0 / ss : 0.0;
    }
    // The learned template turned to angle j (normalised below over the same support; the
    // Gram's units are taken as base's: the template is the recorded pattern's photometry).
    if (refined != nullptr) rotate_pattern(refined, n, j * step_deg, p);
    if (count < 64 || !normalize_pattern(p, n, in.data())) {
      why = "the learned support leaves " + std::to_string(count) + " pixels (or a flat pattern) at angle " +
            std::to_string(j * step_deg) + " deg";
      return nullptr;
    }
    const std::vector<MaskBand> bands = bands_of(in.data(), n);
    b.support_.insert(b.support_.end(), bands.begin(), bands.end());
    b.support_begin_.push_back(b.support_.size());
    b.support_count_.push_back(count);
    // The pattern noise's Gram: base's, over the smaller support (∝ its pixels) and in the
    // renormalised copy's units (a learned support is a setup-side option; not re-simulated).
    if (!base.noise_gram_.empty()) {
      if (b.noise_gram_.empty()) b.noise_gram_.assign(base.noise_gram_.size(), 0.0);
      const double f = noise_factor * renorm * static_cast<double>(count) /
                       std::max<double>(1.0, static_cast<double>(base.support_count_[static_cast<std::size_t>(j)]));
      constexpr std::size_t K2 = kNoiseParams * kNoiseParams;
      for (std::size_t q = 0; q < K2; ++q)
        b.noise_gram_[static_cast<std::size_t>(j) * K2 + q] = f * base.noise_gram_[static_cast<std::size_t>(j) * K2 + q];
    }
  }
  b.pattern_noise_var_ = base.pattern_noise_var_ * noise_factor;
  b.pattern_noise_rho_ = base.pattern_noise_rho_;
  b.measure_plane_grams();
  return bank;
}

double PatternBank::mean_support_count() const noexcept {
  double s = 0;
  for (std::int64_t c : support_count_) s += static_cast<double>(c);
  return support_count_.empty() ? 0.0 : s / static_cast<double>(support_count_.size());
}

std::size_t PatternBank::memory_bytes() const noexcept {
  return spatial_.size() * sizeof(float) + sizeof(Complex) * (spectrum_len_ * angles_ + (coarse_len_ + coarse_wide_len_) * coarse_angles_) +
         support_.size() * sizeof(MaskBand) + support_begin_.size() * sizeof(std::size_t) +
         support_count_.size() * sizeof(std::int64_t) + noise_gram_.size() * sizeof(double) +
         plane_gram_.size() * sizeof(PlaneGram);
}

}  // namespace sempose::pose
