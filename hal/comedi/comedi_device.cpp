#include "sempose/hal/comedi_device.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace sempose::hal {
namespace {

std::string errno_text() { return std::strerror(errno); }

}  // namespace

ComediDevice::ComediDevice(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    throw std::runtime_error("comedi.device: cannot open '" + path + "': " + errno_text() +
                             " (is the driver loaded and the card attached? ls /dev/comedi*)");
  }
  comedi_devinfo di{};
  if (::ioctl(fd_, COMEDI_DEVINFO, &di) < 0) {
    const std::string e = errno_text();
    ::close(fd_);
    throw std::runtime_error("comedi.device: '" + path + "' is not a Comedi device (COMEDI_DEVINFO: " + e + ")");
  }
  driver_ = std::string(di.driver_name, strnlen(di.driver_name, COMEDI_NAMELEN));
  board_ = std::string(di.board_name, strnlen(di.board_name, COMEDI_NAMELEN));
  read_subdev_ = di.read_subdevice;
  write_subdev_ = di.write_subdevice;
  std::vector<comedi_subdinfo> info(di.n_subdevs);
  if (di.n_subdevs > 0 && ::ioctl(fd_, COMEDI_SUBDINFO, info.data()) < 0) {
    const std::string e = errno_text();
    ::close(fd_);
    throw std::runtime_error("comedi: " + path + ": COMEDI_SUBDINFO: " + e);
  }
  for (unsigned i = 0; i < di.n_subdevs; ++i) {
    ComediSubdevice s;
    s.type = info[i].type;
    s.n_chan = info[i].n_chan;
    s.flags = info[i].subd_flags;
    s.maxdata = info[i].maxdata;
    const unsigned n_ranges = info[i].range_type & 0xffff;
    if (!(s.flags & SDF_RANGETYPE) && n_ranges > 0) {
      s.ranges.resize(n_ranges);
      comedi_rangeinfo ri{info[i].range_type, s.ranges.data()};
      if (::ioctl(fd_, COMEDI_RANGEINFO, &ri) < 0) s.ranges.clear();
    }
    subdevs_.push_back(std::move(s));
  }
  subdinfo_ = std::move(info);
}

ComediDevice::~ComediDevice() {
  for (const Mapping& m : maps_) ::munmap(m.addr, m.bytes);
  if (fd_ >= 0) ::close(fd_);
}

void ComediDevice::select_read_subdevice(unsigned sub) {
  if (static_cast<int>(sub) == read_subdev_) return;
  if (::ioctl(fd_, COMEDI_SETRSUBD, sub) < 0) {
    throw std::runtime_error("comedi.ai_subdevice: " + std::to_string(sub) + " cannot be made " + path_ +
                             "'s read subdevice: " + errno_text());
  }
  read_subdev_ = static_cast<int>(sub);
}

void ComediDevice::select_write_subdevice(unsigned sub) {
  if (static_cast<int>(sub) == write_subdev_) return;
  if (::ioctl(fd_, COMEDI_SETWSUBD, sub) < 0) {
    throw std::runtime_error("comedi.ao_subdevice: " + std::to_string(sub) + " cannot be made " + path_ +
                             "'s write subdevice: " + errno_text());
  }
  write_subdev_ = static_cast<int>(sub);
}

int ComediDevice::cmdtest(comedi_cmd& cmd) const {
  int r = 0;
  for (int pass = 0; pass < 5; ++pass) {
    r = ::ioctl(fd_, COMEDI_CMDTEST, &cmd);
    if (r < 0) {
      throw std::runtime_error("comedi: " + path_ + ": COMEDI_CMDTEST on subdevice " + std::to_string(cmd.subdev) +
                               ": " + errno_text());
    }
    if (r == 0 || r == 1 || r == 2 || r == 5) return r;  // valid, or not fixable by adjusting args
  }
  return r;
}

void* ComediDevice::map_buffer(unsigned sub, std::size_t bytes, bool write, std::size_t& mapped_bytes) {
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  const std::size_t want = (bytes + page - 1) / page * page;
  comedi_bufconfig bc{};
  bc.subdevice = sub;
  if (::ioctl(fd_, COMEDI_BUFCONFIG, &bc) < 0) {
    throw std::runtime_error("comedi: " + path_ + ": COMEDI_BUFCONFIG on subdevice " + std::to_string(sub) + ": " +
                             errno_text());
  }
  const std::size_t maximum = bc.maximum_size;
  if (bc.size < want) {
    bc = comedi_bufconfig{};
    bc.subdevice = sub;
    if (want > maximum) bc.maximum_size = static_cast<unsigned>(want);  // needs CAP_SYS_ADMIN
    bc.size = static_cast<unsigned>(want);
    if (::ioctl(fd_, COMEDI_BUFCONFIG, &bc) < 0 || bc.size < want) {
      const char* kind = write ? "write" : "read";
      throw std::runtime_error(
          "comedi: a full-field scan needs a " + std::to_string(want / 1024) + " KiB " + (write ? "AO" : "AI") +
          " buffer; " + path_ + " allows " + std::to_string(maximum / 1024) + " KiB (" + errno_text() +
          "). As root: echo " + std::to_string(want / 1024) + " > /sys/class/comedi/" +
          path_.substr(path_.rfind('/') + 1) + "/max_" + kind + "_buffer_kb, or a smaller scan.field_w/h");
    }
  }
  comedi_bufconfig now{};
  now.subdevice = sub;
  ::ioctl(fd_, COMEDI_BUFCONFIG, &now);
  mapped_bytes = now.size;
  void* p = ::mmap(nullptr, mapped_bytes, write ? PROT_WRITE | PROT_READ : PROT_READ, MAP_SHARED, fd_, 0);
  if (p == MAP_FAILED) {
    throw std::runtime_error("comedi: " + path_ + ": mmap of the " + (write ? "AO" : "AI") + " buffer (" +
                             std::to_string(mapped_bytes) + " bytes): " + errno_text());
  }
  maps_.push_back({p, mapped_bytes});
  return p;
}

bool ComediDevice::command(comedi_cmd& cmd) const noexcept { return ::ioctl(fd_, COMEDI_CMD, &cmd) == 0; }

bool ComediDevice::cancel(unsigned sub) const noexcept { return ::ioctl(fd_, COMEDI_CANCEL, sub) == 0; }

bool ComediDevice::internal_trigger(unsigned sub) const noexcept {
  unsigned data[1] = {0};
  comedi_insn insn{};
  insn.insn = INSN_INTTRIG;
  insn.n = 1;
  insn.data = data;
  insn.subdev = sub;
  return ::ioctl(fd_, COMEDI_INSN, &insn) >= 0;
}

bool ComediDevice::running(unsigned sub) noexcept {
  if (sub >= subdinfo_.size() || ::ioctl(fd_, COMEDI_SUBDINFO, subdinfo_.data()) < 0) return true;  // unknown: wait
  return (subdinfo_[sub].subd_flags & SDF_RUNNING) != 0;
}

bool ComediDevice::bufinfo(comedi_bufinfo& bi) const noexcept { return ::ioctl(fd_, COMEDI_BUFINFO, &bi) == 0; }

bool ComediDevice::write_single(unsigned sub, unsigned chanspec, unsigned value) const noexcept {
  unsigned data[1] = {value};
  comedi_insn insn{};
  insn.insn = INSN_WRITE;
  insn.n = 1;
  insn.data = data;
  insn.subdev = sub;
  insn.chanspec = chanspec;
  return ::ioctl(fd_, COMEDI_INSN, &insn) >= 0;
}

}  // namespace sempose::hal
