// What the checks cannot read from /proc or /sys: a CAN link's kind, bitrate and controller
// state (rtnetlink), whether a GPIO line is already held (the GPIO character device) and
// whether a device node is a Comedi card (its ioctl).
// LinuxProbe asks the running kernel; tests pass their own LiveProbe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace sempose::check_rt {

struct CanLinkDetails {
  std::string kind;           // "can", "vcan", ... (IFLA_INFO_KIND)
  std::uint32_t bitrate = 0;  // 0: none reported (vcan, or not configured)
  std::string state;          // "error-active", "error-warning", "error-passive", "bus-off", "stopped", "" (vcan)
};

struct GpioLineUse {
  bool chip_found = false;
  std::string chip_problem;   // why the chip could not be opened
  bool line_exists = false;
  bool used = false;          // requested by someone (kernel driver or a process)
  std::string consumer;       // who holds it
};

class LiveProbe {
 public:
  virtual ~LiveProbe() = default;
  virtual std::optional<CanLinkDetails> can_link(const std::string& interface) = 0;
  virtual GpioLineUse gpio_line(const std::string& chip, int line) = 0;
  // Why the node at `path` is not a Comedi device the run could open (empty: it is one). A
  // folder, a FIFO or /dev/null passed as "present and writable" where `run` then refused it
  // (found probing): the node is asked what `run` asks it, COMEDI_DEVINFO.
  virtual std::string comedi_problem(const std::string& path) = 0;
};

class LinuxProbe final : public LiveProbe {
 public:
  std::optional<CanLinkDetails> can_link(const std::string& interface) override;
  GpioLineUse gpio_line(const std::string& chip, int line) override;
  std::string comedi_problem(const std::string& path) override;
};

}  // namespace sempose::check_rt
