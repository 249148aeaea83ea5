// External scan control through a Comedi DAQ card (source: comedi). YAML section `comedi:`
// (read_comedi). Two analog outputs deflect the beam (X, Y), one or two analog inputs sample
// the detector; both run as finite Comedi commands clocked together, one AO update per AI
// scan. What the card can really do (minimum sample period, its step, buffer sizes) is only
// known once the device is open: ComediScanSource checks that at setup.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sempose::config {

class Section;

struct ComediConfig {
  std::string device = "/dev/comedi0";
  std::int32_t ai_subdevice = -1;              // -1: the device's default read (AI) subdevice
  std::int32_t ao_subdevice = -1;              // -1: the device's default write (AO) subdevice
  std::vector<std::int32_t> detector_channels{0};  // 1 or 2 AI channels, averaged per pixel
  std::int32_t ai_range = 0;                   // index into the AI subdevice's range table
  std::int32_t x_channel = 0;                  // AO channel of the X deflection
  std::int32_t y_channel = 1;                  // AO channel of the Y deflection
  std::int32_t ao_range = 0;
  // Field calibration: volts at the centre of the field's first and last pixel column/row.
  // Codes are clamped to this span, so the beam can never be sent outside the field.
  std::vector<double> x_volts{-5.0, 5.0};      // [left, right]
  std::vector<double> y_volts{5.0, -5.0};      // [top, bottom]
  std::vector<double> park_volts{0.0, 0.0};    // [x, y] on stop or fault
  // Detector signal mapped to pixel 0 .. max; empty: the AI range's own limits.
  std::vector<double> detector_volts;          // [black, white]
  std::int32_t settle_samples = 4;             // at each line start, beam at the first pixel: dropped
  std::int32_t flyback_samples = 16;           // at each line end, beam ramped back: dropped
  std::int32_t oversample = 1;                 // AI scans per pixel (averaged); dwell = oversample × period
  // internal: AI starts at once (TRIG_NOW), AO by an internal trigger right after (comedi_test);
  // ai_start: AO waits for the AI start trigger (TRIG_EXT, ao_start_arg), AI is started by an
  // internal trigger, so both begin on the same clock edge (NI M-series routing, sem_emul).
  std::string trigger = "internal";
  std::uint32_t ao_start_arg = 0;              // TRIG_EXT argument (routing) for trigger: ai_start
  std::int32_t timeout_ms = 200;               // past the expected scan end: cancelled, frame bad

  // The scan device's path, for tools that check the box (sempose check-rt); "" if unused.
  const std::string& device_path() const noexcept { return device; }
};

void read_comedi(Section& s, ComediConfig& out);

}  // namespace sempose::config
