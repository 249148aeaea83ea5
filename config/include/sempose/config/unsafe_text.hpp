// Characters a name or path must not hold because they change how a line of text reads:
// ASCII controls (a newline breaks every line-oriented tool and log), bytes that are not UTF-8,
// and the Unicode characters that act as controls — C1 controls (U+0085 NEL is a line end to
// many readers, U+009B an 8-bit terminal escape), the line and paragraph separators
// (U+2028/2029), the invisible ones (zero-width spaces and joiners, U+FEFF) and the bidirectional
// overrides (U+202A–202E, U+2066–2069, U+061C), which reorder what a message shows. Zero-width
// joiners (U+200C/200D) are ordinary spelling in Persian and Indic scripts and emoji: allowed in
// paths, refused in target names only (target_name.cpp).
#pragma once

#include <cstddef>
#include <string>

namespace sempose::config {

struct UnsafeCharacter {
  bool found = false;
  std::size_t byte = 0;    // where it starts in the value
  std::size_t length = 0;  // its bytes (1 for an ASCII control or a byte that is not UTF-8)
  std::size_t position = 0;  // 1-based character position (UTF-8 characters counted as one)
  std::string what;        // "a newline (\n)", "U+2028 (a line separator)", "a byte that is not UTF-8"
  std::string escape;      // how printable() writes it: \n, \x01, \u2028, \x85
};

// The first unsafe character at or after byte `from` of `value` (a character's first byte, which
// is character `position_before` + 1): one pass from there, so a caller walking a value from one
// finding to the next reads it once (printable() was quadratic in the value's length).
UnsafeCharacter find_unsafe_character(const std::string& value, std::size_t from = 0, std::size_t position_before = 0);

}  // namespace sempose::config
