#include "sempose/config/unsafe_text.hpp"

#include <cstdio>

namespace sempose::config {
namespace {

std::string ascii_control_name(unsigned char c) {
  switch (c) {
    case 0: return "a NUL byte (\\0)";
    case '\n': return "a newline (\\n)";
    case '\r': return "a carriage return (\\r)";
    case '\t': return "a tab (\\t)";
    case 0x1b: return "an escape (\\x1b)";
    case 0x7f: return "a DEL (\\x7f)";
    default: return "a control character";
  }
}

std::string ascii_escape(unsigned char c) {
  switch (c) {
    case 0: return "\\0";
    case '\n': return "\\n";
    case '\r': return "\\r";
    case '\t': return "\\t";
    default: {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      return buf;
    }
  }
}

// What a Unicode code point that acts as a control is, or nullptr for an ordinary one.
const char* unicode_control_name(char32_t u) {
  if (u >= 0x80 && u <= 0x9f) return u == 0x85 ? "a next-line control (NEL)" : "a C1 control character";
  if (u == 0x200b) return "a zero-width character";
  if (u == 0x200e || u == 0x200f || u == 0x061c) return "a bidirectional mark";
  if (u == 0x2028) return "a line separator";
  if (u == 0x2029) return "a paragraph separator";
  if (u >= 0x202a && u <= 0x202e) return "a bidirectional override";
  if (u >= 0x2066 && u <= 0x2069) return "a bidirectional isolate";
  if ((u >= 0x2060 && u <= 0x2064) || (u >= 0x206a && u <= 0x206f) || u == 0x00ad || u == 0x180e ||
      (u >= 0xe0000 && u <= 0xe007f))
    return "an invisible character";
  if (u == 0xfeff) return "a zero-width no-break space (byte-order mark)";
  return nullptr;
}

// The UTF-8 character at s[i]: its length and code point, or length 0 when the bytes there are
// not UTF-8 (a stray continuation byte, a cut or overlong sequence, a surrogate).
std::size_t decode_utf8(const std::string& s, std::size_t i, char32_t& u) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char c = b(0);
  std::size_t n = 0;
  char32_t min = 0;
  if (c >= 0xc2 && c <= 0xdf) n = 2, u = c & 0x1f, min = 0x80;
  else if (c >= 0xe0 && c <= 0xef) n = 3, u = c & 0x0f, min = 0x800;
  else if (c >= 0xf0 && c <= 0xf4) n = 4, u = c & 0x07, min = 0x10000;
  else return 0;
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xc0) != 0x80) return 0;
    u = (u << 6) | (b(k) & 0x3f);
  }
  if (u < min || u > 0x10ffff || (u >= 0xd800 && u <= 0xdfff)) return 0;
  return n;
}

}  // namespace

UnsafeCharacter find_unsafe_character(const std::string& value, std::size_t from, std::size_t position_before) {
  UnsafeCharacter out;
  std::size_t position = position_before;
  for (std::size_t i = from; i < value.size();) {
    ++position;
    const auto c = static_cast<unsigned char>(value[i]);
    std::size_t len = 1;
    if (c < 0x80) {
      if (i >= from && (c < 0x20 || c == 0x7f)) {
        out = {true, i, 1, position, ascii_control_name(c), ascii_escape(c)};
        return out;
      }
    } else {
      char32_t u = 0;
      len = decode_utf8(value, i, u);
      if (len == 0) {
        if (i >= from) {
          out = {true, i, 1, position, "a byte that is not UTF-8", ascii_escape(c)};
          return out;
        }
        len = 1;
      } else if (const char* name = unicode_control_name(u); name != nullptr && i >= from) {
        char code[32];
        std::snprintf(code, sizeof code, "U+%04X (", static_cast<unsigned>(u));
        char escape[16];
        std::snprintf(escape, sizeof escape, "\\u%04x", static_cast<unsigned>(u));
        out = {true, i, len, position, std::string(code) + name + ")", escape};
        return out;
      }
    }
    i += len;
  }
  return out;
}

}  // namespace sempose::config
