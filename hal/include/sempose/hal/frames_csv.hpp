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
std::vector<std::vector<double>> read_numeric_csv(const std::string& path, std::size_t min_cols);

}  // namespace sempose::hal
