#include "sempose/hal/pgm.hpp"

#include <sys/stat.h>

#include <cctype>
#include <cerrno>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "sempose/hal/cut_file.hpp"

namespace sempose::hal {

namespace {

// What stands at pos as a header field, for a message: up to whitespace or a comment, at most
// 24 bytes, unprintable bytes as '?' ("nothing" at the end of the file).
std::string field_text(const std::vector<unsigned char>& d, std::size_t pos) {
  std::string t;
  while (pos < d.size() && !std::isspace(d[pos]) && d[pos] != '#' && t.size() < 24) {
    t += std::isprint(d[pos]) ? static_cast<char>(d[pos]) : '?';
    ++pos;
  }
  return t.empty() ? std::string("nothing") : "'" + t + (pos < d.size() && !std::isspace(d[pos]) && d[pos] != '#' ? "...'" : "'");
}

// Reads one decimal header field, skipping whitespace and # comments. "" on success, else the
// problem with what was found ("-64", "99999999999": the value was not named, found probing).
std::string next_number(const std::vector<unsigned char>& d, std::size_t& pos, long long& value, const char* name,
                        long long max) {
  for (;;) {
    while (pos < d.size() && std::isspace(d[pos])) ++pos;
    if (pos < d.size() && d[pos] == '#') {
      while (pos < d.size() && d[pos] != '\n' && d[pos] != '\r') ++pos;
      continue;
    }
    break;
  }
  const std::size_t start = pos;
  auto bad = [&] {
    return std::string("header: ") + name + " " + field_text(d, start) + " is not a whole number in 1.." + std::to_string(max) +
           " (digits only, then whitespace)";
  };
  if (pos >= d.size() || !std::isdigit(d[pos])) return bad();
  value = 0;
  while (pos < d.size() && std::isdigit(d[pos])) {
    value = value * 10 + (d[pos] - '0');
    if (value > 1'000'000'000) return bad();
    ++pos;
  }
  // A field ends at whitespace or a comment: "64.0" was read as 64 and its ".0" blamed on the
  // next field (found probing: "missing or bad height" for a bad width).
  if (pos < d.size() && !std::isspace(d[pos]) && d[pos] != '#') return bad();
  return "";
}

std::string parse(const std::vector<unsigned char>& d, Image& out) {
  if (d.size() < 2 || d[0] != 'P' || d[1] != '5') {
    std::string got = d.size() >= 2 ? std::string(d.begin(), d.begin() + 2) : std::string("(empty)");
    for (char& c : got) if (!std::isprint(static_cast<unsigned char>(c))) c = '?';
    return "wrong magic '" + got + "' (expected P5, binary greymap)";
  }
  // "P564 64 255" is not a P5 header (found probing: read as width 64): the magic stands alone.
  if (d.size() > 2 && !std::isspace(d[2]) && d[2] != '#') return "header: no whitespace after the magic P5";
  std::size_t pos = 2;
  long long w = 0, h = 0, maxval = 0;
  for (auto [value, name, max] : {std::tuple{&w, "width", static_cast<long long>(kPgmMaxSide)},
                                   std::tuple{&h, "height", static_cast<long long>(kPgmMaxSide)},
                                   std::tuple{&maxval, "maxval", 65535LL}}) {
    if (std::string why = next_number(d, pos, *value, name, max); !why.empty()) return why;
  }
  if (w <= 0 || h <= 0 || w > kPgmMaxSide || h > kPgmMaxSide) {
    return "size " + std::to_string(w) + "x" + std::to_string(h) + " is outside 1.." +
           std::to_string(kPgmMaxSide) + " per side";
  }
  if (maxval < 1 || maxval > 65535) return "maxval " + std::to_string(maxval) + " is outside 1..65535";
  if (pos >= d.size() || !std::isspace(d[pos])) return "header: no whitespace after maxval";
  ++pos;  // exactly one whitespace byte before the raster
  const std::size_t bytes_per = maxval > 255 ? 2 : 1;
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  const std::size_t need = n * bytes_per;
  if (d.size() - pos < need) {
    return "truncated: " + std::to_string(d.size() - pos) + " of " + std::to_string(need) + " pixel bytes";
  }
  // Bytes beyond the raster mean the header does not describe the data: a comment after
  // maxval shifts the raster by its length, a 16-bit raster under maxval 255 reads as its
  // first half, a second image is not one sempose can use. Each read silently as a wrong image.
  if (d.size() - pos > need) {
    return std::to_string(d.size() - pos - need) + " bytes after the " + std::to_string(w) + "x" + std::to_string(h) +
           " raster of " + std::to_string(need) + " bytes (maxval " + std::to_string(maxval) +
           "): a wrong maxval, a comment after maxval, or a second image";
  }
  Image img;
  img.width = static_cast<std::int32_t>(w);
  img.height = static_cast<std::int32_t>(h);
  img.bits = bytes_per == 2 ? 16 : 8;
  img.pixels.resize(n);
  const unsigned char* p = d.data() + pos;
  for (std::size_t i = 0; i < n; ++i) {
    img.pixels[i] = bytes_per == 2 ? static_cast<std::uint16_t>((p[2 * i] << 8) | p[2 * i + 1]) : p[i];
  }
  // A sample above maxval is not a PGM (netpbm): the header lies about the depth (a 12-bit
  // raster under maxval 255 whose bytes happen to fit, a maxval typed wrong). It was read as it
  // came, brighter than white.
  for (std::size_t i = 0; i < n; ++i) {
    if (img.pixels[i] > maxval) {
      return "sample " + std::to_string(img.pixels[i]) + " at (" + std::to_string(i % static_cast<std::size_t>(w)) + ", " +
             std::to_string(i / static_cast<std::size_t>(w)) + ") is above maxval " + std::to_string(maxval);
    }
  }
  out = std::move(img);
  return {};
}

}  // namespace

bool parse_pgm(const std::vector<unsigned char>& data, Image& out, std::string& error) {
  error = parse(data, out);
  return error.empty();
}

bool try_read_pgm(const std::string& path, Image& out, std::string& error) {
  // Only a regular file is read: a directory "opens" and reads as empty, a FIFO blocks in
  // open() until a writer comes, a character device such as /dev/zero never ends.
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    error = path + ": cannot open (" + std::strerror(errno) + ")";
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = path + ": not a regular file (" +
            (S_ISDIR(st.st_mode) ? "a directory" : S_ISFIFO(st.st_mode) ? "a FIFO" : S_ISCHR(st.st_mode) ? "a character device" : S_ISBLK(st.st_mode) ? "a block device" : "a socket or other special file") +
            ")";
    return false;
  }
  // The largest valid PGM: 16384² 16-bit samples plus a header with comments.
  constexpr long long kMaxBytes = 2ll * kPgmMaxSide * kPgmMaxSide + (1 << 20);
  if (st.st_size > kMaxBytes) {
    error = path + ": " + std::to_string(st.st_size) + " bytes is larger than any PGM of at most " +
            std::to_string(kPgmMaxSide) + " px per side";
    return false;
  }
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    error = path + ": cannot open (" + std::strerror(errno) + ")";
    return false;
  }
  std::vector<unsigned char> data(static_cast<std::size_t>(st.st_size));
  f.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(data.size()));
  data.resize(static_cast<std::size_t>(f.gcount()));
  if (f.bad()) {
    error = path + ": read error";
    return false;
  }
  const std::string why = parse(data, out);
  if (!why.empty()) {
    error = path + ": " + why;
    return false;
  }
  return true;
}

Image read_pgm(const std::string& path) {
  Image img;
  std::string error;
  if (!try_read_pgm(path, img, error)) throw std::runtime_error(error);
  return img;
}

void write_pgm(const std::string& path, const Image& image) {
  if (image.empty() || image.pixels.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw std::runtime_error(path + ": cannot write an empty or inconsistent image");
  }
  const bool wide = image.bits > 8;
  std::string out = "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n" +
                    (wide ? "65535" : "255") + "\n";
  const std::size_t head = out.size();
  out.resize(head + image.pixels.size() * (wide ? 2 : 1));
  char* p = out.data() + head;
  for (std::size_t i = 0; i < image.pixels.size(); ++i) {
    const std::uint16_t v = image.pixels[i];
    if (wide) {
      p[2 * i] = static_cast<char>(v >> 8);
      p[2 * i + 1] = static_cast<char>(v & 0xff);
    } else {
      p[i] = static_cast<char>(v > 255 ? 255 : v);
    }
  }
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error(path + ": cannot create the file (" + std::strerror(errno) + ")");
  f.write(out.data(), static_cast<std::streamsize>(out.size()));
  f.close();
  if (!f) {
    // A cut PGM was left (found probing: `pattern --out` under a file-size limit, 2048 of its
    // bytes); run and replay refuse it later, but it looks like a pattern until then.
    throw std::runtime_error(path + ": write failed (disk full or a file-size limit?); " + cut_file_outcome(remove_cut_file(path)));
  }
}

}  // namespace sempose::hal
