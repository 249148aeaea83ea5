// sempose view's parts: the poses CSV reader (errors name file and line), the PNG writer
// (read back with libpng), and the overlay: drawn at the pose, turned the way sempose turns
// patterns (counter-clockwise on screen), coloured by state.
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sempose/operator_view/pose_csv.hpp"
#include "sempose/operator_view/rgb_image.hpp"
#include "sempose/operator_view/roi_overlay.hpp"
#include "sempose/operator_view/track_plot.hpp"

namespace fs = std::filesystem;
using namespace sempose;
using namespace sempose::operator_view;

namespace {

std::string temp(const std::string& name) {
  return (fs::temp_directory_path() / ("sempose_view_" + std::to_string(::getpid()) + "_" + name)).string();
}

bool same(Rgb a, Rgb b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

// Reading `content` (written to p) must fail with an error that holds `message`.
void expect_read_error(const std::string& p, const std::string& content, const std::string& message) {
  std::ofstream(p) << content;
  try {
    read_pose_csv(p);
    ADD_FAILURE() << "no error for " << content;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
  }
}

}  // namespace

TEST(PoseCsv, ReadsRunAndReplayFiles) {
  const std::string p = temp("poses.csv");
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status,target\n"
                      "0,1000,10.5,20.25,-3.5,0.91,TRACKING,needle\n"
                      "1,2000,11.0,21.0,-3.0,0.20,LOST,gripper\n";
  const auto rows = read_pose_csv(p);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_DOUBLE_EQ(rows[0].y_px, 20.25);
  EXPECT_EQ(rows[1].status, "LOST");
  EXPECT_EQ(targets_of(rows), (std::vector<std::string>{"needle", "gripper"}));
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status\n5,0,1,2,3,0.5,ACQUIRING\n";
  EXPECT_EQ(read_pose_csv(p).front().target, "");
  // Files with the scale column (sempose run), with and without targets.
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale\n0,0,1,2,3,0.5,TRACKING,needle,1.0500\n";
  EXPECT_EQ(read_pose_csv(p).front().target, "needle");
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status,scale\n0,0,1,2,3,0.5,TRACKING,0.9500\n";
  EXPECT_EQ(read_pose_csv(p).front().target, "");
  EXPECT_EQ(read_pose_csv(p).front().angle_order, 1) << "a file that does not say: a full turn";
  // sempose run's columns today: the σ and the angle's rotational order last (a lamella: 2).
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status,target,scale,sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale,angle_order\n"
                      "0,0,1,2,3,0.5,TRACKING,0,1.0,0.1,0.1,0.2,0.001,2\n";
  EXPECT_EQ(read_pose_csv(p).front().angle_order, 2);
  EXPECT_EQ(read_pose_csv(p).front().target, "0");
  // An order no pattern declares, and the column without the σ before it, are files sempose did not write.
  expect_read_error(p,
                    "frame,t_ns,x_px,y_px,phi_deg,score,status,scale,sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale,angle_order\n"
                    "0,0,1,2,3,0.5,TRACKING,1.0,0.1,0.1,0.2,0.001,9\n",
                    p + ":2: angle_order '9' is not a whole number in [1, 6]");
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status,scale,angle_order\n0,0,1,2,3,0.5,TRACKING,1.0,2\n";
  EXPECT_THROW(read_pose_csv(p), std::runtime_error);
  // Saved again by a spreadsheet: a UTF-8 byte-order mark before the header is read past (shown
  // in the error, it made the header look right).
  std::ofstream(p) << "\xEF\xBB\xBF" "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,1,160,120,0,0.9,TRACKING\n";
  ASSERT_EQ(read_pose_csv(p).size(), 1u);
  EXPECT_DOUBLE_EQ(read_pose_csv(p).front().x_px, 160.0);
  fs::remove(p);
}

// The φ plot says which target's angle is known modulo 360°/n only: the lamella's line, not the
// needle's (the .gp file is written whether or not gnuplot is installed).
TEST(TrackPlot, SymmetricTargetsPhiLineSaysModulo) {
  PoseRow lamella, needle;
  lamella.target = "lamella";
  lamella.angle_order = 2;
  needle.target = "needle";
  const std::string stem = temp("track");
  plot_track({lamella, needle}, stem, "t");
  std::ostringstream text;
  text << std::ifstream(stem + ".gp").rdbuf();
  const std::string gp = text.str();
  EXPECT_NE(gp.find("title 'target lamella (mod 180)'"), std::string::npos) << gp;
  EXPECT_EQ(gp.find("target needle (mod"), std::string::npos) << gp;
  EXPECT_NE(gp.find("title 'target needle'"), std::string::npos) << gp;
  for (const char* ext : {".gp", ".dat", ".png"}) fs::remove(stem + ext);
}

// Text from outside never becomes gnuplot commands (found probing `sempose view`): a target name
// from the poses CSV holding a quote, a system() call and a newline, in an output folder whose
// name holds a quote and a system() call. The script quotes the names (a quote doubled, control
// characters as '?') and names its files by their leaf names, gnuplot running in their folder.
TEST(TrackPlot, NamesAndFoldersFromOutsideAreTextNotCommands) {
  const fs::path dir = temp("q'; system('touch PWNED'); print '");
  fs::create_directories(dir);
  const fs::path witness = dir / "PWNED";
  PoseRow a;
  a.target = "x'; system('touch " + witness.string() + "'); print '\nsystem('touch " + witness.string() + "')";
  a.status = "TRACKING";
  PoseRow b = a;
  b.frame = 1;
  b.x_px = 3;
  const std::string stem = (dir / "track").string();
  const std::string problem = plot_track({a, b}, stem, "it's a title");
  std::ostringstream text;
  text << std::ifstream(stem + ".gp").rdbuf();
  const std::string gp = text.str();
  EXPECT_NE(gp.find("title 'target x''; system(''touch "), std::string::npos) << gp;
  EXPECT_NE(gp.find("''); print ''?system(''touch "), std::string::npos) << "the newline shown as '?': " << gp;
  EXPECT_NE(gp.find("set output 'track.png'"), std::string::npos) << gp;
  EXPECT_NE(gp.find("title 'it''s a title'"), std::string::npos) << gp;
  EXPECT_EQ(gp.find(dir.string()), std::string::npos) << "no folder path in the script: " << gp;
  if (problem.find("not found") == std::string::npos) {  // gnuplot installed (ci/setup installs it)
    EXPECT_EQ(problem, "");
    EXPECT_TRUE(fs::exists(stem + ".png")) << "drawn in a folder whose name holds a quote";
  }
  EXPECT_FALSE(fs::exists(witness)) << "a name from outside ran as a command";
  fs::remove_all(dir);
}

// A long run's plot: above 18,000 poses a target's line is drawn from each bucket's extremes
// (gnuplot took over a minute for 200k poses, found probing), and every excursion and every
// pose that was not TRACKING still shows in the data gnuplot draws.
TEST(TrackPlot, ALongRunIsDrawnFromEachBucketsExtremes) {
  std::vector<PoseRow> rows(200000);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].frame = i;
    rows[i].t_ns = static_cast<std::int64_t>(i) * 1'000'000;
    rows[i].x_px = 100 + std::sin(i * 0.01);
    rows[i].y_px = 50;
    rows[i].score = 0.9;
    rows[i].status = "TRACKING";
  }
  rows[123457].x_px = 400;  // one excursion
  rows[77777].status = "LOST";
  rows[77777].score = 0.1;
  const std::string stem = temp("long");
  plot_track(rows, stem, "t");
  std::ifstream dat(stem + ".dat");
  std::size_t lines = 0;
  bool excursion = false, lost = false;
  for (std::string line; std::getline(dat, line);) {
    if (line.empty() || line[0] == '#') continue;
    ++lines;
    std::istringstream in(line);
    double t, frame, x, y, phi, score, tracked;
    in >> t >> frame >> x >> y >> phi >> score >> tracked;
    excursion = excursion || x == 400;
    lost = lost || (frame == 77777 && tracked == 0);
  }
  EXPECT_LE(lines, 18000u) << "the plot's data is bounded";
  EXPECT_GT(lines, 1000u);
  EXPECT_TRUE(excursion) << "a one-pose excursion was dropped";
  EXPECT_TRUE(lost) << "the LOST pose was dropped";
  for (const char* ext : {".gp", ".dat", ".png"}) fs::remove(stem + ext);
}

// t_ns is CLOCK_MONOTONIC (a box up for more than 104 days passes 2^53 ns) or a recording's epoch
// stamps, and the frame counter is 64-bit: view refused sempose's own CSVs beyond 2^53 (found
// probing). Every 64-bit value is read exactly, and times far apart still plot.
TEST(PoseCsv, SixtyFourBitFramesAndTimesAreReadExactly) {
  const std::string p = temp("big_t.csv");
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status\n"
                      "18446744073709551615,9223372036854775807,1,2,3,0.5,TRACKING\n"
                      "0,-9223372036854775808,1,2,3,0.5,TRACKING\n"
                      "9007199254740993,1765000000000000001,1,2,3,0.5,TRACKING\n";
  const auto rows = read_pose_csv(p);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].frame, 18446744073709551615ull);
  EXPECT_EQ(rows[0].t_ns, 9223372036854775807ll);
  EXPECT_EQ(rows[1].t_ns, std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(rows[2].frame, 9007199254740993ull) << "2^53 + 1: not rounded through a double";
  EXPECT_EQ(rows[2].t_ns, 1765000000000000001ll);
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,9223372036854775808,1,2,3,0.5,TRACKING\n",
                    p + ":2: t_ns '9223372036854775808' is not a whole number in [-9223372036854775808, 9223372036854775807]");
  std::ofstream(p) << "frame,t_ns,x_px,y_px,phi_deg,score,status\n"
                      "0,-9223372036854775808,1,2,3,0.5,TRACKING\n1,9223372036854775807,1,2,3,0.5,TRACKING\n";
  const std::string stem = temp("big_t_track");
  plot_track(read_pose_csv(p), stem, "t");
  std::ifstream dat(stem + ".dat");
  std::vector<double> t;
  for (std::string line; std::getline(dat, line);) {
    if (!line.empty() && line[0] != '#') t.push_back(std::stod(line.substr(0, line.find(' '))));
  }
  ASSERT_EQ(t.size(), 2u);
  EXPECT_NEAR(t[1], 1.8446744e10, 1e4) << "the span of the whole int64 range in seconds";
  for (const char* ext : {".gp", ".dat", ".png"}) fs::remove(stem + ext);
}

TEST(PoseCsv, ErrorsNameFileLineAndCell) {
  const std::string p = temp("bad.csv");
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACKING\n1,0,1,zwei,3,0.5,TRACKING\n",
                    p + ":3: 'zwei' is not a number");
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,nan,2,3,0.5,TRACKING\n", p + ":2: 'nan' is not a finite number");
  // Cells sempose never writes: an unknown status, a score outside [-1, 1], a negative, a
  // fractional and a huge frame (the last two were converted with undefined behaviour), a time
  // beyond 64 bits.
  const std::vector<std::pair<std::string, std::string>> cells = {
      {"0,0,1,2,3,0.5,BOGUS", "status 'BOGUS' is not TRACKING, ACQUIRING, LOST or UNCERTAIN"},
      {"0,0,1,2,3,2,TRACKING", "score '2' is not a number in [-1, 1]"},
      {"-1,0,1,2,3,0.5,TRACKING", "frame '-1' is not a whole number"},
      {"1.5,0,1,2,3,0.5,TRACKING", "frame '1.5' is not a whole number"},
      {"1e300,0,1,2,3,0.5,TRACKING", "frame '1e300' is not a whole number"},
      {"0,1e30,1,2,3,0.5,TRACKING", "t_ns '1e30' is not a whole number"},
      // Positions and angles no field or wrap gives (were drawn: a picture of nothing).
      {"0,0,1e300,2,3,0.5,TRACKING", "x_px '1e300' is not a number in [-1e+06, 1e+06]"},
      {"0,0,1,-2e6,3,0.5,TRACKING", "y_px '-2e6' is not a number in [-1e+06, 1e+06]"},
      {"0,0,1,2,1e200,0.5,TRACKING", "phi_deg '1e200' is not a number in [-360, 360]"},
      // A counter sempose writes in digits: "1e0" was read as frame 1 (found probing).
      {"1e0,0,1,2,3,0.5,TRACKING", "frame '1e0' is not a whole number"},
      {"1.0,0,1,2,3,0.5,TRACKING", "frame '1.0' is not a whole number"},
  };
  for (const auto& [row, message] : cells) {
    expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n" + row + "\n", p + ":2: " + message);
  }
  // At most 4 targets (hal::kMaxTargets), by index (run) or name (replay): found probing, a file
  // of 30,000 distinct targets ran for minutes.
  std::string many = "frame,t_ns,x_px,y_px,phi_deg,score,status,target\n";
  for (int t = 0; t < 6; ++t) many += "0,0,1,2,3,0.5,TRACKING,t" + std::to_string(t) + "\n";
  expect_read_error(p, many, p + ":6: target 't4' is a 5th target; sempose tracks at most 4");
  // A target name out of the config's rule (view makes file names of it: two 100-byte names were
  // cut to one file name, found probing), the shown value cut.
  const std::string long_name(100, 'x');
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status,target\n0,0,1,2,3,0.5,TRACKING," + long_name + "\n",
                    p + ":2: target '" + long_name.substr(0, 80) + "...' is not a target name (1..64 bytes");
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status,target\n0,0,1,2,3,0.5,TRACKING,a b\n",
                    p + ":2: target 'a b' is not a target name");
  // A cell is quoted escaped and cut (hostile round 8): a terminal escape reached stderr raw, a NUL
  // ended the message mid-quote, a 2 MB cell was a 2 MB error line.
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0,1,2,3,0.5,TRACK\x1b]0;X\x07ING\n",
                    p + ":2: status 'TRACK\\x1b]0;X\\x07ING' is not TRACKING");
  expect_read_error(p, std::string("frame,t_ns,x_px,y_px,phi_deg,score,status\n0,3\0" "7,1,2,3,0.5,TRACKING\n", 67),
                    p + ":2: t_ns '3\\07' is not a whole number");
  expect_read_error(p, "frame,t_ns,x_px,y_px,phi_deg,score,status\n0,0," + std::string(2'000'000, '1') + ",2,3,0.5,TRACKING\n",
                    p + ":2: '" + std::string(80, '1') + "...' is not a finite number");
  std::ofstream(p) << "x,y\n1,2\n";
  EXPECT_THROW(read_pose_csv(p), std::runtime_error);
  fs::remove(p);
  EXPECT_THROW(read_pose_csv(p), std::runtime_error);  // missing file
}

TEST(Png, WrittenPixelsReadBack) {
  RgbImage img(7, 5);
  img.plot(3, 2, Rgb{200, 10, 30});
  img.plot(6, 4, Rgb{1, 2, 3});
  const std::string p = temp("t.png");
  write_png(p, img);
  png_image in{};
  in.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&in, p.c_str()));
  in.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> px(PNG_IMAGE_SIZE(in));
  ASSERT_TRUE(png_image_finish_read(&in, nullptr, px.data(), 0, nullptr));
  EXPECT_EQ(in.width, 7u);
  EXPECT_EQ(in.height, 5u);
  EXPECT_EQ(px[(2 * 7 + 3) * 3 + 0], 200);
  EXPECT_EQ(px[(2 * 7 + 3) * 3 + 2], 30);
  EXPECT_EQ(px[(4 * 7 + 6) * 3 + 1], 2);
  EXPECT_EQ(px[0], 0);
  fs::remove(p);
  EXPECT_THROW(write_png("/nonexistent-dir/x.png", img), std::runtime_error);
}

TEST(Overlay, HeadingTurnsCounterClockwiseOnScreenAndColourFollowsState) {
  hal::Image frame;
  frame.width = 200;
  frame.height = 200;
  frame.pixels.assign(200 * 200, 128);
  PoseRow pose;
  pose.x_px = 100;
  pose.y_px = 100;
  pose.phi_deg = 90;
  pose.status = "TRACKING";
  const RgbImage img = render_roi(frame, pose, 100, 64, {}, 1);
  const Rgb green{40, 220, 60};
  // The ROI is centred on the pose: the pose is at (50, 50) of the 100 px picture. At +90°
  // the pattern's +x axis points up the screen (y decreasing).
  auto at = [&](int x, int y) { return img.pixels[static_cast<std::size_t>(y) * img.width + x]; };
  EXPECT_TRUE(same(at(50, 50 - 20), green));
  EXPECT_FALSE(same(at(50 + 20, 50), green));
  EXPECT_FALSE(same(at(50, 50 + 20), green));
  pose.status = "LOST";
  const RgbImage lost = render_roi(frame, pose, 100, 64, {}, 1);
  EXPECT_TRUE(same(lost.pixels[static_cast<std::size_t>(30) * 100 + 50], Rgb{235, 40, 40}));
}

TEST(Overlay, PatternEdgesLandOnTheTargetsEdgesAtItsPose) {
  // Pattern: bright right half (edge at u = 0). In the frame the same target sits at (120, 90)
  // turned by 90°: bright above the line y = 90. The pattern's edge points, turned and placed
  // at the pose, must lie on that line.
  hal::Image pattern;
  pattern.width = pattern.height = 32;
  pattern.pixels.resize(32 * 32);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) pattern.pixels[static_cast<std::size_t>(y) * 32 + x] = x >= 16 ? 220 : 30;
  }
  const auto edges = pattern_edge_points(pattern, 0.05);
  ASSERT_FALSE(edges.empty());
  for (const auto& e : edges) {
    EXPECT_LE(std::abs(e.first), 1.0f) << e.first;  // on the step
  }
  hal::Image frame;
  frame.width = 240;
  frame.height = 180;
  frame.pixels.assign(240 * 180, 30);
  for (int y = 0; y < 90; ++y) {
    for (int x = 0; x < 240; ++x) frame.pixels[static_cast<std::size_t>(y) * 240 + x] = 220;
  }
  PoseRow pose;
  pose.x_px = 120;
  pose.y_px = 90;
  pose.phi_deg = 90;
  pose.status = "TRACKING";
  const RgbImage img = render_roi(frame, pose, 64, 32, edges, 1);
  int magenta = 0, on_line = 0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      if (!same(img.pixels[static_cast<std::size_t>(y) * img.width + x], Rgb{255, 0, 255})) continue;
      ++magenta;
      on_line += std::abs(y - 32) <= 2;  // the ROI's row 32 is the frame's y = 90
    }
  }
  EXPECT_GT(magenta, 5);
  EXPECT_EQ(on_line, magenta);
}
