// The CSV writer under faults it meets at run time: the disk full mid-run (and full from the
// start), the file deleted while open, the writer thread falling so far behind that the RT
// side's ring overflows. Each must leave a file of whole lines with its header and be
// counted as a write error (summary, heartbeat's output_fault, exit code 4), never a torn
// line or a silent gap.
//
// A full disk is made with RLIMIT_FSIZE (no root, no mount): the kernel then behaves as on a
// full file system for this file — it takes a write up to the limit (mid-line) and refuses
// the rest (EFBIG with SIGXFSZ ignored), just as ext4/tmpfs do with ENOSPC at the last block.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sempose/pipeline/csv_pose_sink.hpp"

namespace sempose::pipeline {
namespace {

namespace fs = std::filesystem;

std::string temp_dir() {
  std::string t = (fs::temp_directory_path() / "sempose_csv_faults_XXXXXX").string();
  if (::mkdtemp(t.data()) == nullptr) return {};
  return t;
}

PoseRecord pose(std::uint64_t frame) {
  PoseRecord p;
  p.frame_seq = frame;
  p.t_scan_end_ns = static_cast<std::int64_t>(frame) * 1000;
  p.x_px = 100.25 + static_cast<double>(frame);
  p.y_px = 50.5;
  p.phi_deg = 1.5;
  p.score = 0.9f;
  p.state = pose::TrackState::kTracking;
  return p;
}

std::vector<std::string> lines_of(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// The file a sink writes for these poses, line by line (empty when it could not be written).
std::vector<std::string> written_lines(const std::vector<PoseRecord>& poses, bool with_target_column) {
  const std::string dir = temp_dir();
  if (dir.empty()) return {};
  CsvPoseSink sink(dir + "/poses.csv", 16, with_target_column);
  if (!sink.open().ok) return {};
  for (const auto& p : poses) EXPECT_EQ(sink.publish(p, 0), PublishResult::kSent);
  sink.write_pending();
  EXPECT_TRUE(sink.close());
  auto lines = lines_of(dir + "/poses.csv");
  fs::remove_all(dir);
  return lines;
}

std::size_t columns(const std::string& line) { return static_cast<std::size_t>(std::count(line.begin(), line.end(), ',')) + 1; }

// Sets this process's file size limit for its lifetime (the soft limit; restored after).
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &old_);
    old_xfsz_ = ::signal(SIGXFSZ, SIG_IGN);
    rlimit l = old_;
    l.rlim_cur = bytes;
    ok_ = ::setrlimit(RLIMIT_FSIZE, &l) == 0;
  }
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &old_);
    ::signal(SIGXFSZ, old_xfsz_);
  }
  bool ok() const { return ok_; }

 private:
  rlimit old_{};
  sighandler_t old_xfsz_{};
  bool ok_ = false;
};

// Every line whole: the header's column count on every line, the frames in order, none torn.
void expect_whole_lines(const std::vector<std::string>& lines, const std::vector<std::uint64_t>& frames) {
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines[0].rfind("frame,t_ns,", 0), 0u) << "the header first: " << lines[0];
  const std::size_t n = columns(lines[0]);
  ASSERT_EQ(lines.size(), frames.size() + 1);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    EXPECT_EQ(columns(lines[i]), n) << "line " << i << " is torn: '" << lines[i] << "'";
    EXPECT_EQ(lines[i].substr(0, lines[i].find(',')), std::to_string(frames[i - 1])) << "line " << i;
  }
}

TEST(CsvPoseSinkFaults, DiskFullMidRunLeavesWholeLinesAndCountsTheLostOnes) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(dir.empty());
  const std::string path = dir + "/poses.csv";
  CsvPoseSink sink(path, 1024, false);
  ASSERT_TRUE(sink.open().ok);
  std::vector<std::uint64_t> kept;
  for (std::uint64_t f = 0; f < 10; ++f) {
    ASSERT_EQ(sink.publish(pose(f), 0), PublishResult::kSent);
    kept.push_back(f);
  }
  sink.write_pending();
  ASSERT_EQ(sink.write_errors(), 0u);
  {
    // The disk fills: room for less than one more line, so the kernel takes half a line.
    FileSizeLimit full(static_cast<rlim_t>(fs::file_size(path) + 30));
    ASSERT_TRUE(full.ok());
    for (std::uint64_t f = 10; f < 20; ++f) sink.publish(pose(f), 0);
    sink.write_pending();
    EXPECT_EQ(sink.write_errors(), 1u);
    EXPECT_EQ(sink.lost_lines(), 10u);
    EXPECT_EQ(sink.last_errno(), EFBIG);
  }
  // Space is back: the next lines follow the last whole line.
  for (std::uint64_t f = 20; f < 30; ++f) {
    sink.publish(pose(f), 0);
    kept.push_back(f);
  }
  EXPECT_FALSE(sink.close()) << "a run that lost lines must not close as clean";
  EXPECT_EQ(sink.written(), 20u);
  expect_whole_lines(lines_of(path), kept);
  fs::remove_all(dir);
}

TEST(CsvPoseSinkFaults, DiskFullFromTheStartStillGivesTheHeaderOnceThereIsRoom) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(dir.empty());
  const std::string path = dir + "/poses.csv";
  CsvPoseSink sink(path, 1024, true);
  {
    FileSizeLimit full(0);
    ASSERT_TRUE(full.ok());
    ASSERT_TRUE(sink.open().ok) << "a full disk is a counted write error, not a refused start";
    sink.publish(pose(0), 0);
    sink.write_pending();
    EXPECT_GE(sink.write_errors(), 1u);
    EXPECT_EQ(sink.lost_lines(), 1u);
  }
  sink.publish(pose(1), 0);
  sink.publish(pose(2), 0);
  EXPECT_FALSE(sink.close());
  const auto lines = lines_of(path);
  expect_whole_lines(lines, {1, 2});
  if (!lines.empty()) {
    EXPECT_NE(lines[0].find(",target,"), std::string::npos) << lines[0];
  }
  fs::remove_all(dir);
}

// t_ns is the time the pose is valid for: when the beam passed the target (a full-field search
// frame's target tens of ms before its scan's end), the scan's end only when not known.
// (Base: always the scan's end.)
TEST(CsvPoseSink, TimeColumnIsWhenTheBeamPassedTheTarget) {
  PoseRecord seen = pose(1), unknown = pose(2);
  seen.t_scan_end_ns = 80'000'000;
  seen.t_beam_ns = 41'000'000;
  const auto lines = written_lines({seen, unknown}, false);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[1].rfind("1,41000000,", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("2,2000,", 0), 0u) << lines[2];
}

// The last column says what phi_deg means: known modulo 360°/angle_order (a lamella: 2, its φ may
// be φ + 180°), appended so readers that index the columns before it keep working. (Base: no
// such column; a reader could not tell a lamella's φ from a needle's.)
TEST(CsvPoseSink, LastColumnIsTheAngleOrder) {
  PoseRecord needle = pose(1), lamella = pose(2);
  lamella.angle_order = 2;
  const auto lines = written_lines({needle, lamella}, true);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale,sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale,angle_order");
  for (const auto& l : lines) EXPECT_EQ(columns(l), 14u) << l;
  EXPECT_EQ(lines[1].substr(lines[1].rfind(',')), ",1") << lines[1];
  EXPECT_EQ(lines[2].substr(lines[2].rfind(',')), ",2") << lines[2];
}

TEST(CsvPoseSinkFaults, APoseTheWriterCouldNotKeepIsAWriteErrorNotASilentGap) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(dir.empty());
  CsvPoseSink sink(dir + "/poses.csv", 16, false);
  ASSERT_TRUE(sink.open().ok);
  // The non-RT writer falls behind (a slow disk, a stopped reader of stdout): the RT side's
  // ring fills and publish() drops.
  int dropped = 0;
  for (std::uint64_t f = 0; f < 40; ++f) dropped += sink.publish(pose(f), 0) == PublishResult::kDropped;
  ASSERT_GT(dropped, 0);
  EXPECT_EQ(sink.dropped(), static_cast<std::uint64_t>(dropped));
  sink.write_pending();
  EXPECT_EQ(sink.write_errors(), 1u) << "the overflow is reported like any lost write";
  EXPECT_EQ(sink.last_errno(), ENOBUFS);
  sink.write_pending();
  EXPECT_EQ(sink.write_errors(), 1u) << "counted once per overflow, not per flush";
  EXPECT_FALSE(sink.close());
  EXPECT_EQ(sink.written() + sink.dropped(), 40u);
  fs::remove_all(dir);
}

TEST(CsvPoseSinkFaults, LinesWrittenIntoADeletedFileAreCountedLost) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(dir.empty());
  const std::string path = dir + "/poses.csv";
  CsvPoseSink sink(path, 1024, false);
  ASSERT_TRUE(sink.open().ok);
  sink.publish(pose(0), 0);
  sink.write_pending();
  ASSERT_EQ(sink.write_errors(), 0u);
  fs::remove_all(dir);  // an operator cleans the output folder mid-run
  for (std::uint64_t f = 1; f < 6; ++f) sink.publish(pose(f), 0);
  sink.write_pending();
  EXPECT_EQ(sink.write_errors(), 1u);
  EXPECT_EQ(sink.lost_lines(), 5u);
  EXPECT_EQ(sink.last_errno(), ENOENT);
  EXPECT_EQ(sink.written(), 1u);
  EXPECT_FALSE(sink.close());
}

// A run refused after its CSV was opened keeping the last run's lines (its pipeline out of
// memory) wrote its header over their first bytes when the sink closed (found probing: a 13-cell
// header, a stub "_order", then the old 14-cell rows). Opened and dropped before begin(), the
// file is left exactly as it was.
TEST(CsvPoseSinkFaults, ASinkDroppedBeforeItBeganLeavesTheLastRunsFileAlone) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(dir.empty());
  const std::string path = dir + "/poses.csv";
  const std::string last_run =
      "frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale\n0,1,2,3,4,0.9,TRACKING,1,1.0\n";
  std::ofstream(path) << last_run;
  {
    CsvPoseSink sink(path, 16, false);
    ASSERT_TRUE(sink.open_keeping().ok);
    sink.publish(pose(0), 0);
    sink.write_pending();
    EXPECT_TRUE(sink.close());
  }
  std::ostringstream after;
  after << std::ifstream(path).rdbuf();
  EXPECT_EQ(after.str(), last_run);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sempose::pipeline
