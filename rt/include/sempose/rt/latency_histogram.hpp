// Latency histogram with fixed 1 µs buckets plus an overflow count, min, max and sum.
// One writer (an RT thread) records with plain relaxed loads and stores: wait-free, no
// read-modify-write, no allocation. Any number of non-RT readers take snapshots; a snapshot
// taken while the writer runs may be off by the samples in flight, never torn per counter.
#pragma once

#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <span>
#include <string>
#include <vector>
#include "sempose/rt/single_writer_counter.hpp"

namespace sempose::rt {

struct HistogramSnapshot {
  std::string name;
  std::vector<std::uint64_t> buckets;  // buckets[i]: samples with i <= latency_us < i + 1
  std::uint64_t overflows = 0;         // samples >= buckets.size() µs
  std::uint64_t count = 0;             // all samples, overflows included
  std::int64_t min_ns = 0;
  std::int64_t max_ns = 0;
  std::int64_t sum_ns = 0;

  double mean_us() const noexcept;
  // Smallest latency (µs, bucket resolution) at or below which a fraction q of the samples
  // lie; samples in overflow report max. 0 when there are no samples.
  double percentile_us(double q) const noexcept;
  std::uint64_t in_range() const noexcept { return count - overflows; }
};

class LatencyHistogram {
 public:
  static constexpr std::size_t kDefaultBuckets = 10'000;

  explicit LatencyHistogram(std::string name, std::size_t bucket_count = kDefaultBuckets);
  LatencyHistogram(const LatencyHistogram&) = delete;
  LatencyHistogram& operator=(const LatencyHistogram&) = delete;

  // Writer only. Negative values (clock misuse) count as 0.
  void record_ns(std::int64_t latency_ns) noexcept;
  // Writer only: forget everything (e.g. after warm-up).
  void reset() noexcept;

  HistogramSnapshot snapshot() const;
  // The same into a snapshot made earlier by snapshot() (its buckets already sized): no
  // allocation, so a non-RT loop that must keep reporting under memory pressure (`ulimit -v`
  // just above the run's need) can take one each status period and at exit.
  void snapshot_into(HistogramSnapshot& s) const noexcept;
  const std::string& name() const noexcept { return name_; }
  std::size_t bucket_count() const noexcept { return bucket_count_; }

 private:
  static void bump(std::atomic<std::uint64_t>& c) noexcept {
    add_single_writer(c);
  }
  std::string name_;
  std::size_t bucket_count_;
  std::unique_ptr<std::atomic<std::uint64_t>[]> buckets_;
  std::atomic<std::uint64_t> overflows_{0};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::int64_t> min_ns_{0};
  std::atomic<std::int64_t> max_ns_{0};
  std::atomic<std::int64_t> sum_ns_{0};
};

// cyclictest --histogram layout, one column per series (README: Latency histograms):
//   "# Histogram", then per bucket "%06d " + TAB-joined "%06lu" counts, then the
//   "# Total:", "# Min Latencies:", "# Avg Latencies:", "# Max Latencies:",
//   "# Histogram Overflows:" lines. As in cyclictest, Total counts in-range samples.
// The series names go in a leading comment line, which OSADL's tools skip.
void write_cyclictest_histogram(std::ostream& out, std::span<const HistogramSnapshot> series);

// {"series":[{"name":..,"count":..,"min_us":..,"p50_us":..,"p99_us":..,"p999_us":..,
//   "p9999_us":..,"max_us":..,"mean_us":..,"overflows":..}, ...]}
void write_histogram_json(std::ostream& out, std::span<const HistogramSnapshot> series);

}  // namespace sempose::rt
