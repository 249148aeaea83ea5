// Reads the poses CSV that `sempose run` (output.poses_csv) and `sempose replay --out` write:
//   frame,t_ns,x_px,y_px,phi_deg,score,status[,target][,scale[,sigma_x_px,...,sigma_scale[,angle_order]]]
// (target is an index for run, a name for replay). Errors name the file, line and cell.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sempose::operator_view {

struct PoseRow {
  std::uint64_t frame = 0;
  std::int64_t t_ns = 0;
  double x_px = 0, y_px = 0, phi_deg = 0, score = 0;
  std::string status;  // TRACKING, ACQUIRING, LOST, UNCERTAIN
  std::string target;  // "" when the file has one target
  int angle_order = 1; // phi_deg is known modulo 360°/angle_order (1 when the file does not say)
};

// Throws std::runtime_error("file:line: ...") on a malformed file.
std::vector<PoseRow> read_pose_csv(const std::string& path);
// Distinct targets in order of first appearance ("" for a single-target file).
std::vector<std::string> targets_of(const std::vector<PoseRow>& rows);

}  // namespace sempose::operator_view
