#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "sempose/rt/alloc_counter.hpp"
#include "sempose/rt/latency_histogram.hpp"

namespace {

using sempose::rt::HistogramSnapshot;
using sempose::rt::LatencyHistogram;

TEST(LatencyHistogram, PercentilesOfAUniformDistribution) {
  LatencyHistogram h("uniform", 1000);
  for (int us = 0; us < 1000; ++us) h.record_ns(us * 1000 + 500);  // one sample per bucket
  const HistogramSnapshot s = h.snapshot();
  EXPECT_EQ(s.count, 1000u);
  EXPECT_EQ(s.overflows, 0u);
  EXPECT_DOUBLE_EQ(s.percentile_us(0.50), 499.0);
  EXPECT_DOUBLE_EQ(s.percentile_us(0.99), 989.0);
  EXPECT_DOUBLE_EQ(s.percentile_us(1.0), 999.0);
  EXPECT_EQ(s.min_ns, 500);
  EXPECT_EQ(s.max_ns, 999'500);
  EXPECT_NEAR(s.mean_us(), 500.0, 1e-9);
}

TEST(LatencyHistogram, PercentilesOfAnExponentialDistributionMatchTheAnalyticValues) {
  LatencyHistogram h("exp");
  std::mt19937_64 rng(42);
  std::exponential_distribution<double> dist(1.0 / 100.0);  // mean 100 µs
  for (int i = 0; i < 200'000; ++i) h.record_ns(static_cast<std::int64_t>(dist(rng) * 1000.0));
  const HistogramSnapshot s = h.snapshot();
  // Quantile of Exp(mean m) is -m ln(1-q); buckets floor to 1 µs.
  EXPECT_NEAR(s.percentile_us(0.50), 69.3, 2.0);
  EXPECT_NEAR(s.percentile_us(0.99), 460.5, 12.0);
  EXPECT_NEAR(s.mean_us(), 100.0, 1.5);
}

TEST(LatencyHistogram, OverflowsAreCountedAndReportMax) {
  LatencyHistogram h("small", 10);
  h.record_ns(5'000);
  h.record_ns(50'000);
  h.record_ns(-3);  // clock misuse counts as 0, never indexes out of range
  const HistogramSnapshot s = h.snapshot();
  EXPECT_EQ(s.count, 3u);
  EXPECT_EQ(s.overflows, 1u);
  EXPECT_EQ(s.in_range(), 2u);
  EXPECT_EQ(s.buckets[0], 1u);
  EXPECT_DOUBLE_EQ(s.percentile_us(1.0), 50.0);
}

TEST(LatencyHistogram, RecordingDoesNotAllocate) {
  LatencyHistogram h("rt");
  std::uint64_t allocs = 0;
  {
    sempose::rt::alloc::ScopedArm arm;
    for (int i = 0; i < 100'000; ++i) h.record_ns(i * 37);
    allocs = sempose::rt::alloc::this_thread_allocations();
  }
  EXPECT_EQ(allocs, 0u);
}

// The non-RT loop refreshes snapshots made at setup: under an address-space limit just above the
// run's need, a fresh snapshot each status period (80 kB) threw std::bad_alloc mid-run and the run
// ended without its summary (found probing).
TEST(LatencyHistogram, ASnapshotIsRefreshedWithoutAllocating) {
  LatencyHistogram h("e2e");
  HistogramSnapshot s = h.snapshot();
  for (int i = 0; i < 1000; ++i) h.record_ns(250'000 + i);
  std::uint64_t allocs = 0;
  {
    sempose::rt::alloc::ScopedArm arm;
    h.snapshot_into(s);
    allocs = sempose::rt::alloc::this_thread_allocations();
  }
  EXPECT_EQ(allocs, 0u);
  const HistogramSnapshot fresh = h.snapshot();
  EXPECT_EQ(s.count, 1000u);
  EXPECT_EQ(s.buckets, fresh.buckets);
  EXPECT_EQ(s.name, "e2e");
  EXPECT_EQ(s.max_ns, fresh.max_ns);
  EXPECT_DOUBLE_EQ(s.percentile_us(0.99), fresh.percentile_us(0.99));
}

// Reads the dump as OSADL's scripts and gnuplot one-liners do: every line not starting with
// '#' is "bucket count count ...".
TEST(LatencyHistogram, CyclictestLayoutParsesBack) {
  LatencyHistogram a("e2e", 50), b("compute", 50);
  for (int i = 0; i < 40; ++i) a.record_ns(i * 1000 + 10);
  for (int i = 0; i < 7; ++i) b.record_ns(3000);
  b.record_ns(1'000'000);  // overflow
  const std::vector<HistogramSnapshot> series{a.snapshot(), b.snapshot()};
  std::ostringstream out;
  sempose::rt::write_cyclictest_histogram(out, series);
  const std::string text = out.str();

  std::istringstream in(text);
  std::string line;
  int rows = 0;
  std::uint64_t sum_a = 0, sum_b = 0;
  bool saw_total = false, saw_overflow = false;
  while (std::getline(in, line)) {
    if (line.rfind('#', 0) == 0) {
      if (line.rfind("# Total:", 0) == 0) {
        saw_total = true;
        EXPECT_EQ(line, "# Total: 000000040 000000007");
      }
      if (line.rfind("# Histogram Overflows:", 0) == 0) {
        saw_overflow = true;
        EXPECT_EQ(line, "# Histogram Overflows: 00000 00001");
      }
      continue;
    }
    // Exact cyclictest field layout: "%06d " then "%06lu" TAB "%06lu".
    ASSERT_EQ(line.size(), 6u + 1 + 6 + 1 + 6) << line;
    EXPECT_EQ(line[6], ' ');
    EXPECT_EQ(line[13], '\t');
    std::istringstream fields(line);
    int bucket = -1;
    std::uint64_t ca = 0, cb = 0;
    fields >> bucket >> ca >> cb;
    EXPECT_EQ(bucket, rows);
    sum_a += ca;
    sum_b += cb;
    ++rows;
  }
  EXPECT_EQ(rows, 50);
  EXPECT_EQ(sum_a, 40u);
  EXPECT_EQ(sum_b, 7u);
  EXPECT_TRUE(saw_total);
  EXPECT_TRUE(saw_overflow);
  EXPECT_NE(text.find("# Max Latencies: 00039 01000\n"), std::string::npos);
  EXPECT_NE(text.find("# Min Latencies: 00000 00003\n"), std::string::npos);
}

TEST(LatencyHistogram, JsonSummaryHasEveryField) {
  LatencyHistogram a("e2e", 100);
  for (int i = 0; i < 100; ++i) a.record_ns(i * 1000);
  const std::vector<HistogramSnapshot> series{a.snapshot()};
  std::ostringstream out;
  sempose::rt::write_histogram_json(out, series);
  const std::string json = out.str();
  for (const char* key : {"\"name\":\"e2e\"", "\"count\":100", "\"p50_us\":49", "\"p99_us\":98",
                          "\"p999_us\":99", "\"p9999_us\":99", "\"max_us\":99.000",
                          "\"overflows\":0", "\"min_us\":0.000"}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " missing in " << json;
  }
}

}  // namespace
