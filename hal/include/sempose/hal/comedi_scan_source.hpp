// External scan through a Comedi DAQ card (README: Scan through Comedi). Per ROI one finite
// AO command (the raster of RasterWriter: X/Y codes from the field calibration, clamped to
// the field) and one finite AI command (one or two detector channels, `oversample` scans per
// pixel), one AO update per AI scan, started together (trigger: internal | ai_start).
//
// start() arms: cancels leftovers, issues the AO command, writes the whole raster into the
// mmap'd AO buffer, issues the AI command, fires the internal trigger. poll() takes what the
// driver has finished (one COMEDI_BUFINFO ioctl) and assembles it from the mmap'd AI buffer
// into the slot without blocking; wait_fd() is the
// device fd (readable while AI data wait), so acquisition sleeps in poll(2). The scan ends when
// the last sample arrives. A scan whose AI command stopped early (overrun, driver error: seen
// once the expected end has passed), whose data stop coming (timeout_ms past the expected
// end) or whose arming failed is cancelled and reported as a bad frame (kError), never a hang.
// On destruction (stop) the beam is parked at park_volts.
#pragma once

#include <linux/comedi.h>

#include <cstdint>
#include <memory>
#include <string>

#include "sempose/config/comedi_config.hpp"
#include "sempose/hal/comedi_device.hpp"
#include "sempose/hal/comedi_raster.hpp"
#include "sempose/hal/scan_source.hpp"

namespace sempose::hal {

class ComediScanSource final : public ScanSource {
 public:
  struct Counters {
    std::uint64_t scans = 0;        // completed
    std::uint64_t cancelled = 0;    // by cancel()
    std::uint64_t timeouts = 0;     // data stopped coming
    std::uint64_t arm_errors = 0;   // a command ioctl failed at start()
    std::uint64_t stopped = 0;      // the AI command ended in an error / before its last sample
    std::int64_t last_arm_ns = 0;   // cost of the last start() (command ioctls + raster write)
  };
  // What COMEDI_CMDTEST said about the card (setup).
  struct CardTiming {
    std::uint32_t min_period_ns = 0;  // fastest AI scan / AO update period both accept
    std::uint32_t period_step_ns = 1;
    bool ai_convert_timer = false;    // convert_src TRIG_TIMER (multi-channel scans on NI)
  };

  // Setup: opens and checks the device against cfg and limits (subdevice kinds, channels,
  // ranges, volts inside the AO range, the card's timing vs scan.min_dwell_ns/dwell_step_ns,
  // buffer sizes), maps the buffers and parks the beam. Throws std::runtime_error naming the
  // key, the value and the card's limit.
  ComediScanSource(const ScanLimits& limits, const config::ComediConfig& cfg);
  ~ComediScanSource() override;

  const ScanLimits& limits() const noexcept override { return limits_; }
  StartResult start(const ScanRequest& req, FrameSlot& slot) noexcept override;
  PollResult poll() noexcept override;
  std::int64_t now_ns() const noexcept override;
  std::int64_t expected_done_ns() const noexcept override { return slot_ ? expected_end_ns_ : 0; }
  int wait_fd() const noexcept override { return dev_->fd(); }

  // Stops the scan in progress (both commands cancelled); its slot is reported by the next
  // poll() as kError with status kBad. Parks the beam.
  void cancel() noexcept;
  // Sends the beam to comedi.park_volts (single AO writes).
  bool park() noexcept;

  const Counters& counters() const noexcept { return counters_; }
  const CardTiming& timing() const noexcept { return timing_; }
  std::int64_t scans_for(const Roi& roi) const noexcept { return shape_.scans(roi); }
  std::uint32_t sample_period_ns(std::uint32_t dwell_ns) const noexcept { return dwell_ns / shape_.oversample; }
  // One line for the startup log: device, driver, subdevices, timing floor, buffers.
  const std::string& description() const noexcept { return description_; }

 private:
  void fail_scan() noexcept;
  bool drain_available() noexcept;
  template <typename Sample>
  void drain() noexcept;

  ScanLimits limits_;
  config::ComediConfig cfg_;
  std::unique_ptr<ComediDevice> dev_;
  unsigned ai_sub_ = 0, ao_sub_ = 0;
  bool ai_lsampl_ = false, ao_lsampl_ = false;
  RasterShape shape_;
  std::unique_ptr<RasterWriter> writer_;
  std::unique_ptr<PixelAssembler> assembler_;
  CardTiming timing_;
  unsigned park_x_ = 0, park_y_ = 0;
  unsigned ai_chanlist_[2] = {0, 0};
  unsigned ao_chanlist_[2] = {0, 0};
  comedi_cmd ai_cmd_{};
  comedi_cmd ao_cmd_{};
  const unsigned char* ai_buf_ = nullptr;
  unsigned char* ao_buf_ = nullptr;
  std::size_t ai_buf_bytes_ = 0, ao_buf_bytes_ = 0;
  std::size_t ai_sample_bytes_ = 2;

  FrameSlot* slot_ = nullptr;
  bool failed_ = false;
  std::uint64_t seq_ = 0;
  std::int64_t expected_end_ns_ = 0;
  std::int64_t deadline_ns_ = 0;
  std::uint64_t marked_ = 0;    // AI bytes the kernel handed over (marked read) this scan
  std::uint64_t consumed_ = 0;  // AI bytes assembled into the slot this scan
  Counters counters_;
  std::string description_;
};

}  // namespace sempose::hal
