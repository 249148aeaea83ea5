#include "sempose/check_rt/system_tree.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>

namespace sempose::check_rt {

SystemTree::SystemTree(std::string root) : root_(std::move(root)) {
  if (root_.empty()) root_ = "/";
}

std::string SystemTree::path(const std::string& rel) const {
  return root_ == "/" ? "/" + rel : (std::filesystem::path(root_) / rel).string();
}

std::optional<std::string> SystemTree::read(const std::string& rel) const {
  // Only a regular file, and only its first kMaxReadBytes: every file check-rt reads under
  // /proc and /sys is one (a few KiB at most). Found probing `--root` trees: a FIFO there
  // blocked check-rt in open() for good, and /dev/zero linked in read without end.
  constexpr std::size_t kMaxReadBytes = 1 << 20;
  struct stat st {};
  if (::stat(path(rel).c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  std::ifstream in(path(rel), std::ios::binary);
  if (!in) return std::nullopt;
  std::string s;
  char buf[4096];
  while (s.size() < kMaxReadBytes && (in.read(buf, sizeof buf) || in.gcount() > 0)) {
    s.append(buf, static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) return std::nullopt;
  if (s.size() > kMaxReadBytes) s.resize(kMaxReadBytes);
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

bool SystemTree::exists(const std::string& rel) const {
  std::error_code ec;
  return std::filesystem::exists(path(rel), ec);
}

bool SystemTree::writable(const std::string& rel) const { return ::access(path(rel).c_str(), W_OK) == 0; }

std::vector<std::string> SystemTree::list(const std::string& rel_dir) const {
  std::vector<std::string> out;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(path(rel_dir), ec), end; !ec && it != end; it.increment(ec)) {
    out.push_back(it->path().filename().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::optional<std::vector<int>> parse_cpu_list(const std::string& text) {
  // Ranges are collected, then listed once each: a 1 MiB file of "0-65535,0-65535,…" (a fake
  // or corrupt tree) used to be expanded range by range — over a minute and 10 GB of memory.
  constexpr int kMaxCpu = 65535;
  std::vector<std::pair<int, int>> ranges;
  std::string t;
  for (char c : text) {
    if (!std::isspace(static_cast<unsigned char>(c))) t += c;
  }
  if (t.empty() || t == "(null)") return std::vector<int>{};
  std::stringstream ss(t);
  std::string part;
  while (std::getline(ss, part, ',')) {
    const auto dash = part.find('-');
    try {
      std::size_t used = 0;
      if (dash == std::string::npos) {
        const int v = std::stoi(part, &used);
        if (used != part.size() || v < 0 || v > kMaxCpu) return std::nullopt;
        ranges.emplace_back(v, v);
      } else {
        // The kernel's group form "lo-hi:used/group" (bitmap_parselist): of every `group` CPUs
        // from lo, the first `used` ("0-7:2/4" is 0, 1, 4, 5). Read as all CPUs it gave a false
        // PASS for rcu_nocbs=0-3:1/4, which offloads CPU 0 only (hostile round 9).
        std::string b = part.substr(dash + 1);
        int used_per = 1, group = 1;
        bool grouped = false;
        if (const auto colon = b.find(':'); colon != std::string::npos) {
          const std::string g = b.substr(colon + 1);
          const auto slash = g.find('/');
          if (slash == std::string::npos) return std::nullopt;
          std::size_t u1 = 0, u2 = 0;
          const std::string us = g.substr(0, slash), gs = g.substr(slash + 1);
          used_per = std::stoi(us, &u1);
          group = std::stoi(gs, &u2);
          if (u1 != us.size() || u2 != gs.size() || used_per < 1 || group < 1 || used_per > group) return std::nullopt;
          b = b.substr(0, colon);
          grouped = true;
        }
        std::size_t used2 = 0;
        const std::string a = part.substr(0, dash);
        const int lo = std::stoi(a, &used), hi = std::stoi(b, &used2);
        if (used != a.size() || used2 != b.size() || lo < 0 || hi < lo || hi > kMaxCpu) return std::nullopt;
        if (!grouped || used_per == group) {
          ranges.emplace_back(lo, hi);
        } else {
          // Bounded: a 1 MiB list of such parts would otherwise be billions of ranges.
          if (ranges.size() + static_cast<std::size_t>((hi - lo) / group + 1) > (std::size_t{1} << 20)) return std::nullopt;
          for (int g0 = lo; g0 <= hi; g0 += group) ranges.emplace_back(g0, std::min(hi, g0 + used_per - 1));
        }
      }
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }
  std::sort(ranges.begin(), ranges.end());
  std::vector<int> out;
  int next = 0;  // the lowest CPU not listed yet
  for (const auto& [lo, hi] : ranges) {
    for (int v = std::max(lo, next); v <= hi; ++v) out.push_back(v);
    next = std::max(next, hi + 1);
  }
  return out;
}

std::optional<std::vector<int>> parse_cpu_mask(const std::string& text) {
  std::string hex;
  for (char c : text) {
    if (c == ',' || std::isspace(static_cast<unsigned char>(c))) continue;
    if (!std::isxdigit(static_cast<unsigned char>(c))) return std::nullopt;
    hex += c;
  }
  if (hex.empty()) return std::nullopt;
  std::vector<int> out;
  const int n = static_cast<int>(hex.size());
  for (int i = 0; i < n; ++i) {  // i-th digit from the right holds CPUs 4i..4i+3
    const char c = hex[static_cast<std::size_t>(n - 1 - i)];
    const int v = std::isdigit(static_cast<unsigned char>(c)) ? c - '0' : std::tolower(c) - 'a' + 10;
    for (int b = 0; b < 4; ++b) {
      if (v & (1 << b)) out.push_back(4 * i + b);
    }
  }
  return out;
}

std::string format_cpu_list(const std::vector<int>& cpus) {
  std::string out;
  for (std::size_t i = 0; i < cpus.size();) {
    std::size_t j = i;
    while (j + 1 < cpus.size() && cpus[j + 1] == cpus[j] + 1) ++j;
    if (!out.empty()) out += ',';
    out += std::to_string(cpus[i]);
    if (j > i) out += '-' + std::to_string(cpus[j]);
    i = j + 1;
  }
  return out;
}

}  // namespace sempose::check_rt
