// Frame-sync input: a rising edge from the scan generator means "ROI scan complete".
// libgpiod 1.6 v1 C API (README: CAN and GPIO): the line's edge events are requested once at setup;
// the RT side then only reads the event fd (non-blocking) with gpiod_line_event_read_fd,
// which reads into a stack buffer — no allocation, no exceptions (the C++ binding has both).
// Event timestamps are CLOCK_MONOTONIC, taken by the kernel in the IRQ handler.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "sempose/rt/result.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace sempose::hal {

// Anything that delivers timestamped edges through a pollable fd (a GPIO line; a pipe in tests).
class EdgeSource {
 public:
  virtual ~EdgeSource() = default;
  // Readable (POLLIN) when an edge is pending.
  virtual int fd() const noexcept = 0;
  // Takes up to max pending edges without blocking; returns how many (0 when none, -1 error).
  virtual int read_edges(std::int64_t* t_edge_ns, int max) noexcept = 0;
};

struct GpioLineOptions {
  std::string chip;           // name ("gpiochip0"), path ("/dev/gpiochip0"), label or number
  int line = -1;              // offset on the chip
  bool active_low = false;    // a falling electrical edge counts as the "rising" (active) edge
  std::string consumer = "sempose";
};

class GpioFrameSync final : public EdgeSource {
 public:
  // Setup: opens the chip, requests rising-edge events, makes the fd non-blocking.
  // nullptr + message naming chip, line and the failing call.
  static std::unique_ptr<GpioFrameSync> open(const GpioLineOptions& options, rt::Status& status);
  ~GpioFrameSync() override;

  int fd() const noexcept override { return fd_; }
  int read_edges(std::int64_t* t_edge_ns, int max) noexcept override;
  // Waits up to timeout_ns for an edge (poll(2)); true when one is pending. For non-RT use
  // or an acquisition stage that chooses to block on the line.
  bool wait(std::int64_t timeout_ns) const noexcept;

 private:
  GpioFrameSync() = default;
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  int fd_ = -1;
};

}  // namespace sempose::hal
