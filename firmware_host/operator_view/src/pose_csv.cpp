#include "sempose/operator_view/pose_csv.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/target_name.hpp"
#include "sempose/hal/frame.hpp"

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace sempose::operator_view {
namespace {

// Far beyond any scan field (a DAC of 16 bits addresses 65536 positions per axis).
constexpr double kMaxPositionPx = 1e6;

// A cell or line as an error quotes it: control characters escaped (a terminal escape in a cell
// reached stderr raw, a NUL ended the message mid-quote) and at most 80 bytes of it (a 2 MB cell
// was a 2 MB error line; hostile round 8).
std::string cell_text(const std::string& cell) {
  constexpr std::size_t kShown = 80;
  std::size_t cut = std::min(cell.size(), kShown);
  while (cut > 0 && cut < cell.size() && (static_cast<unsigned char>(cell[cut]) & 0xC0) == 0x80) --cut;
  return config::printable(cell.substr(0, cut)) + (cut < cell.size() ? "..." : "");
}

double number(const std::string& cell, const std::string& where) {
  char* end = nullptr;
  const double v = std::strtod(cell.c_str(), &end);
  if (cell.empty() || end != cell.c_str() + cell.size()) throw std::runtime_error(where + ": '" + cell_text(cell) + "' is not a number");
  // A pose sempose writes is always finite; nan/inf would only reach the plot as a gap.
  if (!std::isfinite(v)) throw std::runtime_error(where + ": '" + cell_text(cell) + "' is not a finite number");
  return v;
}

// A number from `lo` to `hi` (the frame counter, a time stamp and a score have ranges; a value
// outside one would be undefined when converted, or a file sempose did not write).
double number_in(const std::string& cell, const std::string& where, const char* what, double lo, double hi,
                 bool whole) {
  const double v = number(cell, where);
  // A whole number in digits: "1e0" or "1.0" as a frame counter is no file sempose wrote.
  const std::string unsigned_part = !cell.empty() && cell[0] == '-' ? cell.substr(1) : cell;
  const bool digits = !unsigned_part.empty() && unsigned_part.find_first_not_of("0123456789") == std::string::npos;
  if (v < lo || v > hi || (whole && (v != std::floor(v) || !digits))) {
    std::ostringstream m;
    m << where << ": " << what << " '" << cell_text(cell) << "' is not " << (whole ? "a whole number" : "a number") << " in [" << lo
      << ", " << hi << "]";
    throw std::runtime_error(m.str());
  }
  return v;
}

// A whole number of the column's own type, read exactly: the frame counter and t_ns are written
// as 64-bit integers (t_ns is CLOCK_MONOTONIC on a box up for more than 104 days, or a
// recording's epoch stamps, beyond the 2^53 a double holds exactly: found probing, `view`
// refused sempose's own CSVs).
template <typename Int>
Int whole_number(const std::string& cell, const std::string& where, const char* what) {
  Int v{};
  const char* end = cell.data() + cell.size();
  const auto [ptr, ec] = std::from_chars(cell.data(), end, v);
  if (cell.empty() || ec != std::errc{} || ptr != end) {
    throw std::runtime_error(where + ": " + what + " '" + cell_text(cell) + "' is not a whole number in [" +
                             std::to_string(std::numeric_limits<Int>::min()) + ", " +
                             std::to_string(std::numeric_limits<Int>::max()) + "]");
  }
  return v;
}

std::string status(const std::string& cell, const std::string& where) {
  for (const char* s : {"TRACKING", "ACQUIRING", "LOST", "UNCERTAIN"}) {
    if (cell == s) return cell;
  }
  throw std::runtime_error(where + ": status '" + cell_text(cell) + "' is not TRACKING, ACQUIRING, LOST or UNCERTAIN");
}

}  // namespace

std::vector<PoseRow> read_pose_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::vector<PoseRow> rows;
  std::string line;
  int n = 0;
  std::vector<std::string> names;  // the targets so far
  bool with_target = false;
  std::size_t columns = 7;
  std::size_t order_column = 0;  // 0: the file has none
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (n == 1) {
      // A UTF-8 byte-order mark (the CSV saved again by a spreadsheet) is read past, as the
      // truth reader does: shown in the error, it made the header look right (found probing).
      if (line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
      if (line.rfind("frame,t_ns,x_px,y_px,phi_deg,score,status", 0) != 0) {
        throw std::runtime_error(path + ":1: header '" + cell_text(line) + "' is not frame,t_ns,x_px,y_px,phi_deg,score,status[,target][,scale]");
      }
      // Columns after status: target (several targets), scale, the four σ and the angle's order
      // (newer files), in that order; the view reads the order (the angle plot says what φ
      // means) and only counts the others.
      std::string rest = line.substr(std::string("frame,t_ns,x_px,y_px,phi_deg,score,status").size());
      const std::string order = ",angle_order";
      const bool with_order = rest.size() >= order.size() && rest.compare(rest.size() - order.size(), order.size(), order) == 0;
      if (with_order) rest.resize(rest.size() - order.size());
      const std::string sigmas = ",sigma_x_px,sigma_y_px,sigma_phi_deg,sigma_scale";
      const bool with_sigma = rest.size() >= sigmas.size() && rest.compare(rest.size() - sigmas.size(), sigmas.size(), sigmas) == 0;
      if (with_sigma) rest.resize(rest.size() - sigmas.size());
      if ((rest != "" && rest != ",target" && rest != ",scale" && rest != ",target,scale") ||
          (with_sigma && rest.find(",scale") == std::string::npos) || (with_order && !with_sigma)) {
        throw std::runtime_error(path + ":1: header '" + cell_text(line) + "' is not frame,t_ns,x_px,y_px,phi_deg,score,status[,target][,scale[" +
                                 sigmas + "[" + order + "]]]");
      }
      with_target = rest.rfind(",target", 0) == 0;
      columns = 7 + (with_target ? 1 : 0) + (rest.find(",scale") != std::string::npos ? 1 : 0) + (with_sigma ? 4 : 0) +
                (with_order ? 1 : 0);
      order_column = with_order ? columns - 1 : 0;
      continue;
    }
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    const std::string where = path + ":" + std::to_string(n);
    if (cells.size() != columns) {
      throw std::runtime_error(where + ": " + std::to_string(cells.size()) + " cells, the header has " + std::to_string(columns));
    }
    PoseRow r;
    r.frame = whole_number<std::uint64_t>(cells[0], where, "frame");
    r.t_ns = whole_number<std::int64_t>(cells[1], where, "t_ns");
    // Positions in a field and angles wrapped to (-180, 180] are what sempose writes; 1e300 px
    // drew a picture of nothing and a track plot whose axis hid every real pose.
    r.x_px = number_in(cells[2], where, "x_px", -kMaxPositionPx, kMaxPositionPx, false);
    r.y_px = number_in(cells[3], where, "y_px", -kMaxPositionPx, kMaxPositionPx, false);
    r.phi_deg = number_in(cells[4], where, "phi_deg", -360, 360, false);
    r.score = number_in(cells[5], where, "score", -1, 1, false);
    r.status = status(cells[6], where);
    // The target column: run's index or replay's name, of at most hal::kMaxTargets targets (found
    // probing: a file of 30,000 distinct targets ran for minutes; each is a line of the plot).
    if (with_target) {
      r.target = cells[7];
      // A name sempose writes keeps the config's rule; view makes file names of it (found probing:
      // two 100-byte names cut to one file name, "6 ROI pictures" and 3 files).
      if (!config::is_target_name(r.target)) {
        throw std::runtime_error(where + ": target '" + cell_text(r.target) + "' is not a target name (1.." +
                                 std::to_string(config::kMaxTargetNameLength) +
                                 " bytes of UTF-8, no spaces, control or invisible characters)");
      }
      if (std::find(names.begin(), names.end(), r.target) == names.end()) {
        if (names.size() == static_cast<std::size_t>(hal::kMaxTargets)) {
          throw std::runtime_error(where + ": target '" + cell_text(r.target) + "' is a " + std::to_string(names.size() + 1) +
                                   "th target; sempose tracks at most " + std::to_string(hal::kMaxTargets));
        }
        names.push_back(r.target);
      }
    }
    // The orders a pattern can declare (pose::PatternSymmetry) are 1..6; more is not a file sempose wrote.
    if (order_column != 0) r.angle_order = static_cast<int>(number_in(cells[order_column], where, "angle_order", 1, 6, true));
    rows.push_back(std::move(r));
  }
  if (rows.empty()) throw std::runtime_error(path + ": no poses");
  return rows;
}

std::vector<std::string> targets_of(const std::vector<PoseRow>& rows) {
  std::vector<std::string> out;
  for (const auto& r : rows) {
    if (std::find(out.begin(), out.end(), r.target) == out.end()) out.push_back(r.target);
  }
  return out;
}

}  // namespace sempose::operator_view
