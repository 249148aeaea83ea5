#include "sempose/config/target_name.hpp"
#include "sempose/config/unsafe_text.hpp"

#include <algorithm>

namespace sempose::config {
namespace {

bool breaks_word(unsigned char ch) { return ch <= ' ' || ch == 0x7f; }

// A space, or a character that is not safe in text (unsafe_text.hpp: a zero-width space made
// "a\u200b" print as "a", a bidirectional override reordered the status line after it).
// Zero-width joiners too (U+200C/200D: allowed in paths, but "a\u200d" prints as "a").
bool breaks_name(const std::string& name) {
  return std::any_of(name.begin(), name.end(), [](unsigned char ch) { return breaks_word(ch); }) ||
         find_unsafe_character(name).found || name.find("\u200c") != std::string::npos ||
         name.find("\u200d") != std::string::npos;
}

bool is_taken(const std::string& name, const std::vector<std::string>& taken) {
  return std::find(taken.begin(), taken.end(), name) != taken.end();
}

}  // namespace

bool is_target_name(const std::string& name) {
  return !name.empty() && name.size() <= kMaxTargetNameLength && !breaks_name(name);
}

std::string make_target_name(const std::string& raw, std::size_t index, const std::vector<std::string>& taken) {
  // Room for a "_N" suffix when the name is taken; not cut inside a UTF-8 character.
  std::size_t cut = std::min(raw.size(), kMaxTargetNameLength - 12);
  while (cut > 0 && cut < raw.size() && (static_cast<unsigned char>(raw[cut]) & 0xC0) == 0x80) --cut;
  std::string base = raw.substr(0, cut);
  std::replace_if(base.begin(), base.end(), [](unsigned char ch) { return breaks_word(ch); }, '_');
  for (UnsafeCharacter u = find_unsafe_character(base); u.found; u = find_unsafe_character(base, u.byte + 1, u.position))
    base.replace(u.byte, u.length, "_");
  for (const char* joiner : {"\u200c", "\u200d"})
    for (std::size_t at = base.find(joiner); at != std::string::npos; at = base.find(joiner, at + 1)) base.replace(at, 3, "_");
  if (base.empty()) base = "target" + std::to_string(index);
  std::string name = base;
  for (std::size_t n = index; is_taken(name, taken); ++n) name = base + "_" + std::to_string(n);
  return name;
}

}  // namespace sempose::config
