#include "sempose/rt/latency_histogram.hpp"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>

namespace sempose::rt {

namespace {
constexpr double kNsPerUs = 1000.0;

std::string fmt(const char* f, std::uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, f, static_cast<unsigned long>(v));
  return buf;
}
}  // namespace

double HistogramSnapshot::mean_us() const noexcept {
  return count == 0 ? 0.0 : static_cast<double>(sum_ns) / static_cast<double>(count) / kNsPerUs;
}

double HistogramSnapshot::percentile_us(double q) const noexcept {
  if (count == 0) return 0.0;
  q = std::clamp(q, 0.0, 1.0);
  const auto rank = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count))));
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < buckets.size(); ++i) {
    seen += buckets[i];
    if (seen >= rank) return static_cast<double>(i);
  }
  return static_cast<double>(max_ns) / kNsPerUs;
}

LatencyHistogram::LatencyHistogram(std::string name, std::size_t bucket_count)
    : name_(std::move(name)),
      bucket_count_(bucket_count),
      buckets_(new std::atomic<std::uint64_t>[bucket_count]) {
  for (std::size_t i = 0; i < bucket_count_; ++i) buckets_[i].store(0, std::memory_order_relaxed);
}

void LatencyHistogram::record_ns(std::int64_t latency_ns) noexcept {
  latency_ns = std::max<std::int64_t>(latency_ns, 0);
  const auto us = static_cast<std::uint64_t>(latency_ns / 1000);
  if (us < bucket_count_) {
    bump(buckets_[us]);
  } else {
    bump(overflows_);
  }
  const std::uint64_t n = count_.load(std::memory_order_relaxed);
  if (n == 0 || latency_ns < min_ns_.load(std::memory_order_relaxed)) {
    min_ns_.store(latency_ns, std::memory_order_relaxed);
  }
  if (latency_ns > max_ns_.load(std::memory_order_relaxed)) {
    max_ns_.store(latency_ns, std::memory_order_relaxed);
  }
  sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + latency_ns, std::memory_order_relaxed);
  // Release: a reader that sees the new count also sees the bucket it belongs to.
  count_.store(n + 1, std::memory_order_release);
}

void LatencyHistogram::reset() noexcept {
  for (std::size_t i = 0; i < bucket_count_; ++i) buckets_[i].store(0, std::memory_order_relaxed);
  overflows_.store(0, std::memory_order_relaxed);
  min_ns_.store(0, std::memory_order_relaxed);
  max_ns_.store(0, std::memory_order_relaxed);
  sum_ns_.store(0, std::memory_order_relaxed);
  count_.store(0, std::memory_order_release);
}

HistogramSnapshot LatencyHistogram::snapshot() const {
  HistogramSnapshot s;
  s.name = name_;
  s.buckets.resize(bucket_count_);
  snapshot_into(s);
  return s;
}

void LatencyHistogram::snapshot_into(HistogramSnapshot& s) const noexcept {
  s.count = count_.load(std::memory_order_acquire);
  const std::size_t n = std::min(bucket_count_, s.buckets.size());
  for (std::size_t i = 0; i < n; ++i) {
    s.buckets[i] = buckets_[i].load(std::memory_order_relaxed);
  }
  s.overflows = overflows_.load(std::memory_order_relaxed);
  s.min_ns = min_ns_.load(std::memory_order_relaxed);
  s.max_ns = max_ns_.load(std::memory_order_relaxed);
  s.sum_ns = sum_ns_.load(std::memory_order_relaxed);
}

void write_cyclictest_histogram(std::ostream& out, std::span<const HistogramSnapshot> series) {
  std::size_t rows = 0;
  for (const auto& s : series) rows = std::max(rows, s.buckets.size());
  out << "# sempose latency histogram, 1 us buckets; series:";
  for (const auto& s : series) out << ' ' << s.name;
  out << "\n# Histogram\n";
  for (std::size_t i = 0; i < rows; ++i) {
    out << fmt("%06lu", i) << ' ';
    for (std::size_t j = 0; j < series.size(); ++j) {
      const auto& b = series[j].buckets;
      out << fmt("%06lu", i < b.size() ? b[i] : 0) << (j + 1 < series.size() ? "\t" : "");
    }
    out << '\n';
  }
  auto line = [&](const char* label, const char* f, auto value) {
    out << label;
    for (const auto& s : series) out << ' ' << fmt(f, value(s));
    out << '\n';
  };
  line("# Total:", "%09lu", [](const HistogramSnapshot& s) { return s.in_range(); });
  line("# Min Latencies:", "%05lu",
       [](const HistogramSnapshot& s) { return static_cast<std::uint64_t>(s.min_ns / 1000); });
  line("# Avg Latencies:", "%05lu",
       [](const HistogramSnapshot& s) { return static_cast<std::uint64_t>(s.mean_us()); });
  line("# Max Latencies:", "%05lu",
       [](const HistogramSnapshot& s) { return static_cast<std::uint64_t>(s.max_ns / 1000); });
  line("# Histogram Overflows:", "%05lu", [](const HistogramSnapshot& s) { return s.overflows; });
}

void write_histogram_json(std::ostream& out, std::span<const HistogramSnapshot> series) {
  out << "{\"bucket_us\":1,\"series\":[";
  for (std::size_t j = 0; j < series.size(); ++j) {
    const auto& s = series[j];
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "{\"name\":\"%s\",\"count\":%" PRIu64 ",\"min_us\":%.3f,\"mean_us\":%.3f,"
                  "\"p50_us\":%.0f,\"p99_us\":%.0f,\"p999_us\":%.0f,\"p9999_us\":%.0f,"
                  "\"max_us\":%.3f,\"overflows\":%" PRIu64 "}",
                  s.name.c_str(), s.count, static_cast<double>(s.min_ns) / kNsPerUs, s.mean_us(),
                  s.percentile_us(0.50), s.percentile_us(0.99), s.percentile_us(0.999),
                  s.percentile_us(0.9999), static_cast<double>(s.max_ns) / kNsPerUs, s.overflows);
    out << (j ? "," : "") << buf;
  }
  out << "]}\n";
}

}  // namespace sempose::rt
