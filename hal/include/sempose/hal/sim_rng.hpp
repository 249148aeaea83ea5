// Fast deterministic random numbers for the simulated SEM: xoshiro256** seeded through
// splitmix64 from (seed, stream) — e.g. (config seed, frame seq) — so a frame is reproducible
// on its own. No state outside the object, no allocation: usable in the RT loop.
// Samplers for the detector model: Poisson (electron counts), Gamma (the gain cascade: the
// sum of n Gamma(k) gains is Gamma(n·k)), Gaussian (read noise, line jitter).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace sempose::hal {

// Inverse normal CDF at 4096 quantiles (Acklam's approximation, |error| < 1.2e-9), for a fast
// table-driven normal in the per-pixel loop. Built on first use (the simulator's setup).
struct NormalTable {
  static constexpr int kSize = 4096;
  std::array<float, kSize + 1> q{};
  std::array<double, 256> inv{};  // 1/k for the Poisson recursion (no division per step)
  NormalTable() noexcept {
    for (std::size_t k = 1; k < inv.size(); ++k) inv[k] = 1.0 / static_cast<double>(k);
    for (int i = 0; i <= kSize; ++i) q[static_cast<std::size_t>(i)] = static_cast<float>(inverse_cdf((i + 0.5) / (kSize + 1)));
  }
  static double inverse_cdf(double p) noexcept {
    static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                   1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00};
    static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                   6.680131188771972e+01, -1.328068155288572e+01};
    static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                   -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00};
    static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                   3.754408661907416e+00};
    if (p < 0.02425) {
      const double s = std::sqrt(-2 * std::log(p));
      return (((((c[0] * s + c[1]) * s + c[2]) * s + c[3]) * s + c[4]) * s + c[5]) /
             ((((d[0] * s + d[1]) * s + d[2]) * s + d[3]) * s + 1);
    }
    if (p > 1 - 0.02425) return -inverse_cdf(1 - p);
    const double s = p - 0.5, r = s * s;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * s /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  }
  static const NormalTable& get() noexcept {
    static const NormalTable table;
    return table;
  }
};

class SimRng {
 public:
  SimRng(std::uint64_t seed, std::uint64_t stream) noexcept : table_(&NormalTable::get()) { reseed(seed, stream); }

  void reseed(std::uint64_t seed, std::uint64_t stream) noexcept {
    std::uint64_t x = seed ^ (stream * 0x9E3779B97F4A7C15ull) ^ 0xD1B54A32D192ED03ull;
    for (auto& s : s_) s = splitmix64(x);
    has_spare_ = false;
  }

  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  // Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  // Uniform in (0, 1]: safe for log().
  double uniform_pos() noexcept { return static_cast<double>((next() >> 11) + 1) * 0x1.0p-53; }

  // Standard normal (Marsaglia polar method; caches the second value).
  double normal() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double m = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * m;
    has_spare_ = true;
    return u * m;
  }

  // Standard normal from the quantile table, linearly interpolated (tails clipped at ±3.7σ):
  // a few ns, for the per-pixel noise where the exact tail does not matter.
  float fast_normal() noexcept {
    const std::uint64_t r = next();
    const auto i = static_cast<std::size_t>(r >> 52);                       // 12 bits: bin
    const float f = static_cast<float>((r >> 28) & 0xFFFFFF) * 0x1.0p-24f;  // 24 bits: position
    return table_->q[i] + f * (table_->q[i + 1] - table_->q[i]);
  }

  // Gamma(shape) for the detector cascade: Wilson–Hilferty's cube of a normal for shape >= 2
  // (mean and variance within 1% there, one table normal), Marsaglia–Tsang below.
  double fast_gamma(double shape) noexcept {
    if (shape < 2.0) return gamma(shape);
    const double c = 1.0 / (9.0 * shape);
    const double v = 1.0 - c + fast_normal() * std::sqrt(c);
    return v <= 0.0 ? 0.0 : shape * v * v * v;
  }

  // Poisson(mean): sequential inversion of the CDF with one uniform for small means — the
  // SEM regime of a few electrons per pixel — and a rounded normal approximation above 40.
  // A whole number as a double: a long dwell at a high beam current asks for more electrons
  // than 32 bits hold (100 nA for 0.1 s: ~6e10 a pixel), and the cast to an integer was
  // undefined there (a 0.1 s frame at 100 nA came out black).
  double poisson(double mean) noexcept {
    if (!(mean > 0.0)) return 0;
    if (mean < 40.0) {
      const double u = uniform();
      double p = std::exp(-mean);
      double cdf = p;
      std::uint32_t k = 0;
      while (u > cdf && k < 200) {
        ++k;
        p *= mean * table_->inv[k];
        cdf += p;
      }
      return static_cast<double>(k);
    }
    const double v = std::floor(mean + std::sqrt(mean) * normal() + 0.5);
    return v <= 0.0 ? 0.0 : v;
  }

  // Gamma(shape, scale 1) by Marsaglia–Tsang; shape < 1 via the u^(1/shape) boost.
  double gamma(double shape) noexcept {
    if (!(shape > 0.0)) return 0.0;
    double boost = 1.0;
    if (shape < 1.0) {
      boost = std::pow(uniform_pos(), 1.0 / shape);
      shape += 1.0;
    }
    const double d = shape - 1.0 / 3.0;
    const double c = 1.0 / std::sqrt(9.0 * d);
    for (;;) {
      double x, v;
      do {
        x = normal();
        v = 1.0 + c * x;
      } while (v <= 0.0);
      v = v * v * v;
      const double u = uniform_pos();
      const double x2 = x * x;
      if (u < 1.0 - 0.0331 * x2 * x2) return d * v * boost;
      if (std::log(u) < 0.5 * x2 + d * (1.0 - v + std::log(v))) return d * v * boost;
    }
  }

  // A value in [0,1) from a counter (stateless; trajectory knots, jump targets).
  static double hash_uniform(std::uint64_t seed, std::uint64_t a, std::uint64_t b) noexcept {
    std::uint64_t x = seed ^ (a * 0xBF58476D1CE4E5B9ull) ^ (b * 0x94D049BB133111EBull);
    return static_cast<double>(splitmix64(x) >> 11) * 0x1.0p-53;
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  static std::uint64_t splitmix64(std::uint64_t& x) noexcept {
    std::uint64_t z = (x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  const NormalTable* table_;
  std::uint64_t s_[4]{};
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace sempose::hal
