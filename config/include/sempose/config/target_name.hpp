// A target's name labels it in the status lines, the summary and the logs, which scripts read
// as whitespace-separated fields: one word of 1..64 bytes (UTF-8: an accented letter is two),
// no spaces, control or invisible characters (unsafe_text.hpp), and one target per name. The config reader refuses a name that breaks the rule;
// `sempose replay`, which names targets after their pattern files, makes one that keeps it.
#pragma once

#include <string>
#include <vector>

namespace sempose::config {

inline constexpr std::size_t kMaxTargetNameLength = 64;

bool is_target_name(const std::string& name);

// `raw` made a target name (characters that break the rule become '_', cut to fit, "targetN"
// if nothing is left) that none of `taken` has.
std::string make_target_name(const std::string& raw, std::size_t index, const std::vector<std::string>& taken);

}  // namespace sempose::config
