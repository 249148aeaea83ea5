// Opening the configured GPIO chip, with a cause a user can act on. gpiod_chip_open_lookup()
// takes a name, a number or a path; a path to something that is no chip (a folder, a file)
// failed with ENOENT, "No such file or directory", for a path that exists (found probing).
#pragma once

#include <gpiod.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace sempose::hal {

// The chip, or nullptr with `why` set.
inline gpiod_chip* open_gpio_chip(const std::string& chip, std::string& why) {
  gpiod_chip* c = gpiod_chip_open_lookup(chip.c_str());
  if (c != nullptr) return c;
  const int err = errno;
  struct stat st {};
  if (::stat(chip.c_str(), &st) == 0 && !S_ISCHR(st.st_mode)) {
    why = std::string("it is ") + (S_ISDIR(st.st_mode) ? "a folder" : "not a character device") + ", not a GPIO chip";
  } else {
    why = std::strerror(err);
  }
  return nullptr;
}

}  // namespace sempose::hal
