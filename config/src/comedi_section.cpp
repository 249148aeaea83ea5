#include <string>

#include "sempose/config/comedi_config.hpp"
#include "sempose/config/reader.hpp"

namespace sempose::config {
namespace {

// A [a, b] pair of volts within a DAQ card's possible output (no card goes beyond ±100 V).
// True when the pair was read whole: an item out of range is read as 0, so [1e300, -1e300] was
// also called "equal" after its two range errors (found probing); the callers compare only a
// pair read whole.
bool volts_pair(Section& s, const char* key, std::vector<double>& v, bool may_be_empty) {
  const std::size_t errors_before = s.errors().messages().size();
  s.opt_list(key, v, -100.0, 100.0);
  if (v.empty() && may_be_empty) return false;
  if (v.size() != 2) {
    s.error(key, std::to_string(v.size()) + " value(s) given; expected two, e.g. [-5, 5]");
    return false;
  }
  return s.errors().messages().size() == errors_before;
}

}  // namespace

void read_comedi(Section& s, ComediConfig& out) {
  s.opt("device", out.device);
  if (out.device.empty()) {
    s.error("device", "is empty (a Comedi device node, e.g. /dev/comedi0)");
  } else if (out.device[0] != '/') {
    // check-rt reads the node from its root (/), run from its working folder: a relative path
    // was "missing" to one and opened by the other (hostile round 10).
    s.error("device", "'" + out.device + "' is a relative path: give the device node's absolute path (e.g. /dev/comedi0)");
  }
  s.opt("ai_subdevice", out.ai_subdevice, -1, 255);
  s.opt("ao_subdevice", out.ao_subdevice, -1, 255);
  s.opt_list("detector_channels", out.detector_channels, 0, 255);
  if (out.detector_channels.empty() || out.detector_channels.size() > 2) {
    s.error("detector_channels", std::to_string(out.detector_channels.size()) +
                                     " channel(s) given; allowed: 1 or 2 detector channels");
  } else if (out.detector_channels.size() == 2 && out.detector_channels[0] == out.detector_channels[1]) {
    s.error("detector_channels", "the same channel twice");
  }
  s.opt("ai_range", out.ai_range, 0, 255);
  s.opt("x_channel", out.x_channel, 0, 255);
  s.opt("y_channel", out.y_channel, 0, 255);
  if (out.x_channel == out.y_channel) {
    s.error("y_channel", std::to_string(out.y_channel) + " is the same AO channel as comedi.x_channel");
  }
  s.opt("ao_range", out.ao_range, 0, 255);
  const bool x_whole = volts_pair(s, "x_volts", out.x_volts, false);
  const bool y_whole = volts_pair(s, "y_volts", out.y_volts, false);
  volts_pair(s, "park_volts", out.park_volts, false);
  const bool detector_whole = volts_pair(s, "detector_volts", out.detector_volts, true);
  if (x_whole && out.x_volts[0] == out.x_volts[1]) {
    s.error("x_volts", "left and right are equal: the field would have no width");
  }
  if (y_whole && out.y_volts[0] == out.y_volts[1]) {
    s.error("y_volts", "top and bottom are equal: the field would have no height");
  }
  if (detector_whole && out.detector_volts[0] == out.detector_volts[1]) {
    s.error("detector_volts", "black and white are equal");
  }
  s.opt("settle_samples", out.settle_samples, 0, 100'000);
  s.opt("flyback_samples", out.flyback_samples, 0, 100'000);
  s.opt("oversample", out.oversample, 1, 64);
  s.opt_choice("trigger", out.trigger, {"internal", "ai_start"});
  s.opt("ao_start_arg", out.ao_start_arg);
  s.opt("timeout_ms", out.timeout_ms, 1, 60'000);
}

}  // namespace sempose::config
