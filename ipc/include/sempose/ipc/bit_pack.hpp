// Little-endian ("Intel", DBC @1) bit fields inside a CAN payload, plus the saturating
// double -> integer conversion every fixed-point signal uses. Pure, noexcept, no allocation.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace sempose::ipc {

// Writes the low `bits` bits of value at bit `start` (bit 0 = LSB of byte 0, DBC Intel order).
// Byte-wise (at most 9 steps for a 64-bit field), not bit-wise: this runs for every frame.
constexpr void put_bits(std::uint8_t* data, unsigned start, unsigned bits, std::uint64_t value) noexcept {
  unsigned done = 0;
  while (done < bits) {
    const unsigned pos = start + done;
    const unsigned off = pos % 8;
    const unsigned n = (8 - off) < (bits - done) ? (8 - off) : (bits - done);
    const auto mask = static_cast<std::uint8_t>(((1u << n) - 1u) << off);
    const auto chunk = static_cast<std::uint8_t>(((value >> done) << off) & mask);
    data[pos / 8] = static_cast<std::uint8_t>((data[pos / 8] & ~mask) | chunk);
    done += n;
  }
}

constexpr std::uint64_t get_bits(const std::uint8_t* data, unsigned start, unsigned bits) noexcept {
  std::uint64_t v = 0;
  unsigned done = 0;
  while (done < bits) {
    const unsigned pos = start + done;
    const unsigned off = pos % 8;
    const unsigned n = (8 - off) < (bits - done) ? (8 - off) : (bits - done);
    const std::uint64_t chunk = (static_cast<unsigned>(data[pos / 8]) >> off) & ((1u << n) - 1u);
    v |= chunk << done;
    done += n;
  }
  return v;
}

// Two's-complement sign extension of a `bits`-wide field.
constexpr std::int64_t get_signed_bits(const std::uint8_t* data, unsigned start, unsigned bits) noexcept {
  const std::uint64_t raw = get_bits(data, start, bits);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  return static_cast<std::int64_t>((raw ^ sign)) - static_cast<std::int64_t>(sign);
}

constexpr std::int64_t signed_max(unsigned bits) noexcept { return (std::int64_t{1} << (bits - 1)) - 1; }
constexpr std::int64_t signed_min(unsigned bits) noexcept { return -(std::int64_t{1} << (bits - 1)); }
constexpr std::uint64_t unsigned_max(unsigned bits) noexcept {
  return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
}

// Rounds to nearest and clamps into [lo, hi]; NaN becomes `nan_value` (bad input at run time
// degrades to a defined value, never to undefined behaviour of a float->int cast).
inline std::int64_t saturate_round(double v, std::int64_t lo, std::int64_t hi, std::int64_t nan_value = 0) noexcept {
  if (std::isnan(v)) return nan_value;
  if (v <= static_cast<double>(lo)) return lo;
  if (v >= static_cast<double>(hi)) return hi;
  const auto r = static_cast<std::int64_t>(std::llround(v));
  return r < lo ? lo : (r > hi ? hi : r);
}

constexpr std::int64_t clamp_i64(std::int64_t v, std::int64_t lo, std::int64_t hi) noexcept {
  return v < lo ? lo : (v > hi ? hi : v);
}

}  // namespace sempose::ipc
