// The `frames.csv` of a recorded sequence (`sempose sim` writes it, replay reads it):
//   frame,t_ns            header line (further columns are allowed and ignored)
//   0,1000000             one row per frame: PGM index (0-based, in name order), scan start ns
// Every row is checked before it is used: both fields whole numbers (no sign, fraction,
// exponent, NaN, inf or overflow), the frame inside [0, frame_count), no frame twice, every
// frame present, t_ns in [0, 2^62). Problems name the file, the line and the field.
// Setup only (allocates, throws std::runtime_error).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sempose::hal {

// t_ns per frame index from the file's text; `where` names the file in messages.
std::vector<std::int64_t> parse_frames_csv(const std::string& text, std::size_t frame_count, const std::string& where);
// Reads the file (a regular file of at most 64 MiB) and parses it.
std::vector<std::int64_t> read_frames_csv(const std::string& path, std::size_t frame_count);

// The other CSVs of a recording (ground_truth.csv: frame,x_px,y_px,phi_deg[,target]): the
// numeric fields of every row after the header; a cell that is no number, a row with fewer
// than min_cols fields or a file that cannot be opened throws, naming file and line.
// `lines`, when given, gets each row's line number in the file.
std::vector<std::vector<double>> read_numeric_csv(const std::string& path, std::size_t min_cols,
                                                  std::vector<std::size_t>* lines = nullptr);

// One row of a ground_truth.csv (frame,x_px,y_px,phi_deg[,target]; target 0 when absent).
struct TruthRow {
  long long frame = 0;
  int target = 0;
  double x_px = 0, y_px = 0, phi_deg = 0;
};
// The truth as replay compares with it: frame and target whole numbers >= 0 (target below
// max_targets) and at most one row per frame and target — a frame of 1.5 was read as frame 1,
// -3 or a target of 0.5 dropped without a word, and of two rows for one frame the last one won
// silently. Each of these throws naming the file, the line and the cell (a second row: both
// lines). A row whose pose is not finite is skipped (no truth on that frame), counted in
// non_finite_rows; a pose beyond ±1e7 px or ±1e6° throws. A header that names x, y and the angle
// is read by those names wherever they stand (x or the angle in other units throws); a header of
// names of its own is read by place; a first line of numbers is a row. not_read: what is not
// compared — the header's other columns by name, or without names the cells past the 5th.
std::vector<TruthRow> read_truth_csv(const std::string& path, int max_targets, std::size_t* non_finite_rows = nullptr,
                                     std::string* not_read = nullptr);

}  // namespace sempose::hal
