// Fast deterministic random numbers for the simulated SEM: xoshiro256** seeded through
// splitmix64 from (seed, stream) — e.g. (config seed, frame seq) — so a frame is reproducible
// on its own. No state outside the object, no allocation: usable in the RT loop.
// Samplers for the detector model: Poisson (electron counts), Gamma (the gain cascade: the
// sum of n Gamma(k) gains is Gamma(n·k)), Gaussian (read noise, line jitter).
#pragma once

#include <cmath>
#include <cstdint>

namespace sempose::hal {

class SimRng {
 public:
  SimRng(std::uint64_t seed, std::uint64_t stream) noexcept { reseed(seed, stream); }

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

  // Poisson(mean): product-of-uniforms (Knuth) for small means — the SEM regime of a few
  // electrons per pixel — and a rounded normal approximation above 40.
  std::uint32_t poisson(double mean) noexcept {
    if (!(mean > 0.0)) return 0;
    if (mean < 40.0) {
      const double limit = std::exp(-mean);
      double p = uniform_pos();
      std::uint32_t k = 0;
      while (p > limit) {
        p *= uniform_pos();
        ++k;
      }
      return k;
    }
    const double v = std::floor(mean + std::sqrt(mean) * normal() + 0.5);
    return v <= 0.0 ? 0u : static_cast<std::uint32_t>(v);
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
  std::uint64_t s_[4]{};
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace sempose::hal
