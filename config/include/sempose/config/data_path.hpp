// Where data files named in a config (simulator textures and backgrounds) are found.
// A relative path is looked up, in this order, in the config file's folder, in the installed
// data folder (<prefix>/share/sempose, where the package puts data/sem/...), and in the source
// tree's config/ folder; a binary run from its own build tree tries its source tree before the
// installed folder, so that an installed package never stands in for the checkout under test. The built-in default target names
// data/sem/needle_contact_eb.pgm, so config/default.yaml, /etc/sempose/sempose.yaml and a test's
// own YAML all find it without a path of their own.
#pragma once

#include <string>
#include <vector>

namespace sempose::config {

// The folders a relative data path is tried in, in order (config_path may be empty: code-made
// configs have no file, so only the data folders are tried).
std::vector<std::string> data_search_dirs(const std::string& config_path);

// Resolves `file` to the first candidate that is a readable regular file. On failure returns
// false and sets `problem` to what was wrong, naming every place tried ("not found (tried: a, b)",
// "is a directory, not a file", ...).
bool find_data_file(const std::string& file, const std::string& config_path, std::string& resolved,
                    std::string& problem);

}  // namespace sempose::config
