// One open Comedi device through the kernel's own interface (<linux/comedi.h> ioctls and the
// mmap'd command buffers), without libcomedi: every per-scan call is one ioctl on a fixed,
// preallocated struct, so nothing here can allocate, lock or print on the RT path, and the
// product builds wherever the kernel's UAPI headers are (linux-libc-dev), card or not.
//
// Setup methods throw std::runtime_error naming the device and what failed; the RT methods
// are noexcept and return false (errno kept) on failure.
#pragma once

#include <linux/comedi.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sempose::hal {

struct ComediSubdevice {
  unsigned type = 0;     // COMEDI_SUBD_AI, COMEDI_SUBD_AO, ...
  unsigned n_chan = 0;
  unsigned flags = 0;    // SDF_*
  unsigned maxdata = 0;
  std::vector<comedi_krange> ranges;  // the subdevice's range table (empty: per channel)
  bool lsampl() const noexcept { return (flags & SDF_LSAMPL) != 0; }
  std::size_t bytes_per_sample() const noexcept { return lsampl() ? 4 : 2; }
};

class ComediDevice {
 public:
  explicit ComediDevice(const std::string& path);  // opens O_RDWR | O_NONBLOCK
  ~ComediDevice();
  ComediDevice(const ComediDevice&) = delete;
  ComediDevice& operator=(const ComediDevice&) = delete;

  const std::string& path() const noexcept { return path_; }
  int fd() const noexcept { return fd_; }
  const std::string& driver() const noexcept { return driver_; }
  const std::string& board() const noexcept { return board_; }
  int default_read_subdevice() const noexcept { return read_subdev_; }
  int default_write_subdevice() const noexcept { return write_subdev_; }
  const std::vector<ComediSubdevice>& subdevices() const noexcept { return subdevs_; }

  // The subdevices the fd's read() / write() / mmap(PROT_READ / PROT_WRITE) refer to.
  void select_read_subdevice(unsigned sub);
  void select_write_subdevice(unsigned sub);
  // COMEDI_CMDTEST until the driver stops adjusting (at most 5 passes). Returns the last
  // result (0: the command as adjusted is valid; 1/2: a trigger source is unsupported).
  int cmdtest(comedi_cmd& cmd) const;
  // Sets the subdevice's buffer to at least `bytes` (raising its maximum when allowed) and
  // maps it; returns the mapping. Throws naming the size the card allows.
  void* map_buffer(unsigned sub, std::size_t bytes, bool write, std::size_t& mapped_bytes);

  // ---- RT path ----
  bool command(comedi_cmd& cmd) const noexcept;
  bool cancel(unsigned sub) const noexcept;
  bool internal_trigger(unsigned sub) const noexcept;
  // Marks `done_bytes` as read (read subdevice) or written (write subdevice) and returns the
  // buffer position.
  bool bufinfo(comedi_bufinfo& bi) const noexcept;
  bool write_single(unsigned sub, unsigned chanspec, unsigned value) const noexcept;
  // Whether a command still runs on `sub` (COMEDI_SUBDINFO into a buffer sized at setup). A
  // command that stopped before its last sample stopped on an error (overrun, underrun).
  bool running(unsigned sub) noexcept;

 private:
  std::string path_;
  int fd_ = -1;
  std::string driver_, board_;
  int read_subdev_ = -1, write_subdev_ = -1;
  std::vector<ComediSubdevice> subdevs_;
  std::vector<comedi_subdinfo> subdinfo_;  // running(): preallocated
  struct Mapping {
    void* addr;
    std::size_t bytes;
  };
  std::vector<Mapping> maps_;
};

}  // namespace sempose::hal
