#include "sempose/hal/frames_csv.hpp"

#include <sys/stat.h>

#include <cctype>
#include <cerrno>
#include <initializer_list>
#include <vector>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <utility>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace sempose::hal {

namespace {

constexpr std::int64_t kMaxTimeNs = std::int64_t{1} << 62;  // far beyond any run, no overflow when added to
constexpr long long kMaxFileBytes = 64ll << 20;

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && (s[a] == ' ' || s[a] == '\t' || s[a] == '\r')) ++a;
  while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\t' || s[b - 1] == '\r')) --b;
  return s.substr(a, b - a);
}

std::string shown_number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", v);
  return text;
}

std::string shown(const std::string& s) {
  std::string out = s.size() > 40 ? s.substr(0, 40) + "..." : s;
  for (char& c : out) if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  return out;
}

// A whole number of decimal digits only, at most `max`; false otherwise.
bool parse_count(const std::string& cell, std::int64_t max, std::int64_t& out) {
  if (cell.empty() || cell.size() > 19) return false;
  std::int64_t v = 0;
  for (char c : cell) {
    if (c < '0' || c > '9') return false;
    if (v > (max - (c - '0')) / 10) return false;  // v·10 + digit would pass max (no overflow)
    v = v * 10 + (c - '0');
  }
  out = v;
  return true;
}


// One CSV cell as a number, the whole cell (blanks and a CR aside): "12abc" was read as 12,
// "0x1p3" as 8.
bool whole_cell_number(const std::string& cell, double& v) {
  char* end = nullptr;
  v = std::strtod(cell.c_str(), &end);
  while (*end == ' ' || *end == '\t' || *end == '\r') ++end;
  return end != cell.c_str() && *end == '\0' && cell.find_first_of("xX") == std::string::npos;
}
}  // namespace

std::vector<std::int64_t> parse_frames_csv(const std::string& text, std::size_t frame_count, const std::string& where) {
  std::vector<std::int64_t> t_ns(frame_count, 0);
  std::vector<std::size_t> line_of(frame_count, 0);
  std::size_t pos = 0, line_no = 0;
  bool header = true;
  auto fail = [&](const std::string& what) { throw std::runtime_error(where + ":" + std::to_string(line_no) + ": " + what); };
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string line = trim(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    // Exactly two columns, header and rows: a third column (another file's layout, e.g.
    // ground_truth.csv's frame,x_px,..., or a hand edit) used to be dropped without a word.
    const std::size_t columns = static_cast<std::size_t>(std::count(line.begin(), line.end(), ',')) + 1;
    if (header) {
      header = false;
      // A UTF-8 byte-order mark (a spreadsheet's "CSV UTF-8") was shown as "'???frame,t_ns'".
      if (line.rfind("\xEF\xBB\xBF", 0) == 0) {
        fail("the file begins with a UTF-8 byte-order mark (bytes EF BB BF) before the header 'frame,t_ns': save it "
             "without one");
      }
      if (line.rfind("frame", 0) != 0) fail("expected the header 'frame,t_ns', got '" + shown(line) + "'");
      if (columns != 2) {
        fail("the header has " + std::to_string(columns) + " columns, expected 2 (frame,t_ns), got '" + shown(line) + "'");
      }
      continue;
    }
    if (line.empty()) continue;
    const std::size_t comma = line.find(',');
    if (comma == std::string::npos) fail("expected 'frame,t_ns', got '" + shown(line) + "'");
    if (columns != 2) fail("the row has " + std::to_string(columns) + " columns, expected 2 (frame,t_ns), got '" + shown(line) + "'");
    const std::string f = trim(line.substr(0, comma));
    const std::string t = trim(line.substr(comma + 1));
    std::int64_t frame = 0, ns = 0;
    const auto last = static_cast<std::int64_t>(frame_count) - 1;
    if (!parse_count(f, std::max<std::int64_t>(last, 0), frame) || frame > last) {
      fail("frame '" + shown(f) + "' is not a frame index in [0, " + std::to_string(last) + "] (" +
           std::to_string(frame_count) + " PGM frames)");
    }
    if (!parse_count(t, kMaxTimeNs - 1, ns)) {
      fail("t_ns '" + shown(t) + "' is not a whole number of nanoseconds in [0, 2^62)");
    }
    const auto i = static_cast<std::size_t>(frame);
    if (line_of[i] != 0) fail("frame " + f + " is listed twice (first on line " + std::to_string(line_of[i]) + ")");
    line_of[i] = line_no;
    t_ns[i] = ns;
  }
  if (header) throw std::runtime_error(where + ": empty (expected the header 'frame,t_ns' and one row per frame)");
  for (std::size_t i = 0; i < frame_count; ++i) {
    if (line_of[i] == 0) throw std::runtime_error(where + ": frame " + std::to_string(i) + " has no t_ns row");
  }
  // A frame is scanned after the one before it: time going back (or standing) would give the
  // governor and the motion model a negative or zero frame time.
  for (std::size_t i = 1; i < frame_count; ++i) {
    if (t_ns[i] <= t_ns[i - 1]) {
      throw std::runtime_error(where + ":" + std::to_string(line_of[i]) + ": frame " + std::to_string(i) + "'s t_ns " +
                               std::to_string(t_ns[i]) + " is not after frame " + std::to_string(i - 1) + "'s " +
                               std::to_string(t_ns[i - 1]) + " (time stamps must increase with the frame index)");
    }
  }
  return t_ns;
}

std::vector<std::int64_t> read_frames_csv(const std::string& path, std::size_t frame_count) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  if (!S_ISREG(st.st_mode)) throw std::runtime_error(path + ": not a regular file");
  if (st.st_size > kMaxFileBytes) throw std::runtime_error(path + ": larger than 64 MiB");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::string text(static_cast<std::size_t>(st.st_size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return parse_frames_csv(text, frame_count, path);
}

std::vector<std::vector<double>> read_numeric_csv(const std::string& path, std::size_t min_cols,
                                                  std::vector<std::size_t>* lines) {
  // Only a regular file is read: a FIFO named ground_truth.csv in a recording blocked replay in
  // open() for ever, a directory read as a file of no rows (no truth, no word).
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  if (!S_ISREG(st.st_mode)) {
    throw std::runtime_error(path + ": not a regular file (" +
                             std::string(S_ISDIR(st.st_mode) ? "a directory" : S_ISFIFO(st.st_mode) ? "a FIFO" : "a device or socket") +
                             ")");
  }
  if (st.st_size > kMaxFileBytes) throw std::runtime_error(path + ": larger than 64 MiB");
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::vector<std::vector<double>> rows;
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(f, line)) {
    ++line_no;
    if (line_no == 1 || line.empty()) continue;  // header
    std::vector<double> row;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      double v = 0;
      if (!whole_cell_number(cell, v)) {
        throw std::runtime_error(path + ":" + std::to_string(line_no) + ": '" + shown(cell) + "' is not a number");
      }
      // A number too large for a double reads as inf, which a truth takes for "not on this frame"
      // (found probing: 1e400 px warned and dropped its row where 1e308 was refused as out of range).
      if (std::isinf(v) && cell.find_first_of("iI") == std::string::npos) {
        throw std::runtime_error(path + ":" + std::to_string(line_no) + ": '" + shown(cell) + "' is beyond a double's range");
      }
      row.push_back(v);
    }
    if (row.size() < min_cols) {
      throw std::runtime_error(path + ":" + std::to_string(line_no) + ": expected at least " + std::to_string(min_cols) + " columns");
    }
    rows.push_back(std::move(row));
    if (lines) lines->push_back(line_no);
  }
  return rows;
}

namespace {
const char* const kTruthNames[] = {"frame", "x_px", "y_px", "phi_deg", "target"};

// Where a truth file's quantities stand: frame, x_px, y_px, phi_deg, target (-1: none).
struct TruthLayout {
  std::vector<double> first_row;  // the first line's numbers when it is a row (no header)
  int col[5] = {0, 1, 2, 3, 4};
  bool by_name = false;           // the header named the columns: a row's 5th cell is not the target
  bool target_named = false;      // ... and the target's among them
  std::string not_read;           // header columns read by no one, named for the caller's warning
  std::size_t named_cells = 0;    // the header's cells (by name), or 5 (by place)
};

// A truth file's first line is its header. One that names x, y and the angle (frame,x_px,y_px,
// phi_deg[,target] or their short names) is read by those names wherever they stand, and its
// other columns are not read (named for a warning). Found probing: a 5th column `scale` was read
// as the target index (every row some other target's: nothing compared, exit 0), and `x_nm`,
// `phi_rad` were compared as pixels and degrees (hostile round 12); y before x was read by place
// (round 5). A column named for x, y or the angle in other units is refused. A header of names of
// its own (f,a,b,c: none of x, y, angle) is read by place, as hand-made truths are, and a first
// line of numbers is a row (a file without a header lost it).
TruthLayout truth_layout(const std::string& path) {
  TruthLayout layout;
  std::ifstream f(path);
  std::string line;
  if (!std::getline(f, line)) return layout;
  std::vector<std::string> cells;
  std::vector<double> numbers;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) {
    double v = 0;
    if (whole_cell_number(cell, v)) numbers.push_back(v);
    cell = trim(cell);
    std::transform(cell.begin(), cell.end(), cell.begin(), [](unsigned char c) { return std::tolower(c); });
    cells.push_back(cell);
  }
  if (!cells.empty() && numbers.size() == cells.size()) {
    if (numbers.size() < 4) throw std::runtime_error(path + ":1: expected at least 4 columns");
    layout.first_row = numbers;
    return layout;
  }
  const std::string header = "the header '" + shown(trim(line)) + "'";
  const std::initializer_list<const char*> names[] = {{"frame", "frame_seq", "frame_index"}, {"x", "x_px"}, {"y", "y_px"},
                                                      {"phi", "phi_deg", "angle", "angle_deg", "theta", "theta_deg"},
                                                      {"target", "target_index"}};
  int found[5] = {-1, -1, -1, -1, -1};
  for (std::size_t i = 0; i < cells.size(); ++i) {
    for (int q = 0; q < 5; ++q) {
      if (std::find_if(names[q].begin(), names[q].end(), [&](const char* n) { return cells[i] == n; }) == names[q].end()) continue;
      if (found[q] >= 0) {
        throw std::runtime_error(path + ":1: " + header + " names " + kTruthNames[q] + " twice (columns " +
                                 std::to_string(found[q] + 1) + " and " + std::to_string(i + 1) + ")");
      }
      found[q] = static_cast<int>(i);
    }
    // x, y or the angle in other units (x_nm, phi_rad): compared as pixels and degrees they lie.
    // (Other columns, x_sigma say, are not read and named.)
    for (const char* stem : {"x_", "y_", "phi_", "angle_", "theta_"}) {
      if (cells[i].rfind(stem, 0) != 0) continue;
      const std::string unit = cells[i].substr(std::string(stem).size());
      for (const char* other : {"nm", "um", "\u00b5m", "mm", "m", "rad", "mrad", "urad"}) {
        if (unit != other) continue;
        throw std::runtime_error(path + ":1: " + header + " has '" + cells[i] + "' in column " + std::to_string(i + 1) +
                                 ": the truth is compared in pixels and degrees (x_px, y_px, phi_deg); convert the column "
                                 "and name it so");
      }
    }
  }
  if (found[1] < 0 && found[2] < 0 && found[3] < 0) return layout;  // names of its own: by place
  for (int q = 0; q < 4; ++q) {
    if (found[q] < 0) {
      throw std::runtime_error(path + ":1: " + header + " has no " + kTruthNames[q] +
                               " column: a header naming the columns needs frame, x_px, y_px and phi_deg (target optional)");
    }
  }
  layout.by_name = true;
  layout.named_cells = std::max<std::size_t>(cells.size(), found[4] < 0 && cells.size() == 4 ? 5 : 0);
  for (int q = 0; q < 5; ++q) layout.col[q] = found[q];
  layout.target_named = found[4] >= 0;
  // A 5th cell past a header of four names is the target by place, as frame,x_px,y_px,phi_deg[,target] says.
  if (found[4] < 0 && cells.size() == 4) layout.col[4] = 4;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    if (std::find(std::begin(found), std::end(found), static_cast<int>(i)) != std::end(found)) continue;
    layout.not_read += std::string(layout.not_read.empty() ? "" : ", ") + "'" + shown(cells[i]) + "' (column " +
                       std::to_string(i + 1) + ")";
  }
  return layout;
}
}  // namespace

std::vector<TruthRow> read_truth_csv(const std::string& path, int max_targets, std::size_t* non_finite_rows,
                                     std::string* not_read) {
  std::vector<std::size_t> lines;
  const std::vector<std::vector<double>> rows = read_numeric_csv(path, 4, &lines);
  const TruthLayout layout = truth_layout(path);
  const int* col = layout.col;
  const std::size_t needed = layout.by_name ? static_cast<std::size_t>(*std::max_element(col, col + (layout.target_named ? 5 : 4))) + 1 : 4;
  std::vector<TruthRow> truth;
  std::map<std::pair<long long, int>, std::size_t> line_of;  // (frame, target) -> its line
  std::size_t non_finite = 0, widest = 0;
  auto take = [&](const std::vector<double>& r, std::size_t line) {
    widest = std::max(widest, r.size());
    const std::string at = path + ":" + std::to_string(line) + ": ";
    if (r.size() < needed) {
      throw std::runtime_error(at + "expected at least " + std::to_string(needed) + " columns (the header names column " +
                               std::to_string(needed) + "), got " + std::to_string(r.size()));
    }
    auto whole = [](double v, double below) { return v >= 0 && v < below && v == std::floor(v); };
    if (!whole(r[col[0]], 1e15)) {
      throw std::runtime_error(at + "frame " + shown_number(r[col[0]]) + " is not a frame index (a whole number >= 0)");
    }
    // The target: the named column, or by place the 5th (a header of names of its own, none).
    const int target_col = layout.by_name ? col[4] : 4;
    const bool has_target = target_col >= 0 && r.size() > static_cast<std::size_t>(target_col);
    if (has_target && !whole(r[target_col], max_targets)) {
      throw std::runtime_error(at + "target " + shown_number(r[target_col]) + " is not a target index in [0, " +
                               std::to_string(max_targets - 1) + "]");
    }
    // A pose no scan field holds (1e308 px gave rms_px=inf and a 300-digit max): refused. Non-finite
    // is the target not on that frame (`sempose sim` writes nan there), counted for the caller.
    for (int k = 1; k <= 3; ++k) {
      const double limit = k == 3 ? 1e6 : 1e7;
      if (std::isfinite(r[col[k]]) && std::fabs(r[col[k]]) > limit) {
        throw std::runtime_error(at + kTruthNames[k] + " " + shown_number(r[col[k]]) + " is out of range [" +
                                 shown_number(-limit) + ", " + shown_number(limit) + "]");
      }
    }
    TruthRow t{static_cast<long long>(r[col[0]]), has_target ? static_cast<int>(r[target_col]) : 0, r[col[1]], r[col[2]],
               r[col[3]]};
    if (const auto [it, fresh] = line_of.emplace(std::make_pair(t.frame, t.target), line); !fresh) {
      throw std::runtime_error(at + "a second row for frame " + std::to_string(t.frame) + " target " +
                               std::to_string(t.target) + " (the first is on line " + std::to_string(it->second) +
                               "): which one is the truth?");
    }
    if (std::isfinite(t.x_px) && std::isfinite(t.y_px) && std::isfinite(t.phi_deg)) truth.push_back(t);
    else ++non_finite;
  };
  if (!layout.first_row.empty()) take(layout.first_row, 1);
  for (std::size_t i = 0; i < rows.size(); ++i) take(rows[i], lines[i]);
  if (non_finite_rows) *non_finite_rows = non_finite;
  // What is not compared: the header's unread columns by name, and cells past the header's
  // columns (by place: past the 5th).
  if (not_read) {
    const std::size_t named = layout.by_name ? layout.named_cells : 5;
    *not_read = layout.not_read;
    if (widest > named) {
      *not_read += std::string(not_read->empty() ? "" : ", ") + "columns " + std::to_string(named + 1) + ".." +
                   std::to_string(widest) + (layout.by_name ? " (past the header's)" : "");
    }
  }
  return truth;
}

}  // namespace sempose::hal
