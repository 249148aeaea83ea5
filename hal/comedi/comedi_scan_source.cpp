#include "sempose/hal/comedi_scan_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "sempose/hal/scan_request_check.hpp"
#include "sempose/rt/clock.hpp"

namespace sempose::hal {
namespace {

std::string fmt_v(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

double range_lo(const comedi_krange& r) { return r.min * 1e-6; }
double range_hi(const comedi_krange& r) { return r.max * 1e-6; }

// Nominal code of `volts` in a range (the card's own calibration is not applied; the field
// calibration in volts absorbs a linear gain/offset error of the card).
double code_of(double volts, const comedi_krange& r, unsigned maxdata) {
  return (volts - range_lo(r)) / (range_hi(r) - range_lo(r)) * maxdata;
}

unsigned clamp_code(double code, unsigned maxdata) {
  return static_cast<unsigned>(std::lround(std::clamp(code, 0.0, static_cast<double>(maxdata))));
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& m : v) s += (s.empty() ? "" : "\n") + m;
  return s;
}

// Probes the fastest scan period a command accepts and the step between accepted periods.
struct Probe {
  int result = 0;
  std::uint32_t min_ns = 0, step_ns = 1;
};
Probe probe_period(const ComediDevice& dev, comedi_cmd base) {
  Probe p;
  comedi_cmd c = base;
  c.scan_begin_arg = 1;
  p.result = dev.cmdtest(c);
  if (p.result != 0) return p;
  p.min_ns = c.scan_begin_arg;
  for (std::uint32_t d : {1u, 2u, 5u, 10u, 20u, 50u, 100u, 200u, 500u, 1000u, 2000u, 5000u, 10000u, 100000u}) {
    comedi_cmd t = base;
    t.scan_begin_arg = p.min_ns + d;
    if (dev.cmdtest(t) == 0 && t.scan_begin_arg > p.min_ns) {
      p.step_ns = t.scan_begin_arg - p.min_ns;
      break;
    }
  }
  return p;
}

}  // namespace

ComediScanSource::ComediScanSource(const ScanLimits& limits, const config::ComediConfig& cfg)
    : limits_(limits), cfg_(cfg) {
  dev_ = std::make_unique<ComediDevice>(cfg.device);
  const auto& subs = dev_->subdevices();
  const std::string who = cfg.device + " (" + dev_->driver() + ", " + dev_->board() + ")";
  std::vector<std::string> problems;

  auto pick = [&](const char* key, std::int32_t configured, int fallback, unsigned type, unsigned cmd_flag,
                  const char* what) -> int {
    const int sub = configured >= 0 ? configured : fallback;
    if (sub < 0) {
      problems.push_back(std::string("comedi.") + key + ": -1 (the default) but " + who + " has no default " + what +
                         " subdevice; name one");
    } else if (sub >= static_cast<int>(subs.size())) {
      problems.push_back(std::string("comedi.") + key + ": " + std::to_string(sub) + " is outside [0, " +
                         std::to_string(subs.size() - 1) + "], the subdevices of " + who);
    } else if (subs[sub].type != type || !(subs[sub].flags & cmd_flag)) {
      problems.push_back(std::string("comedi.") + key + ": subdevice " + std::to_string(sub) + " of " + who +
                         " is not an " + what + " subdevice that takes commands (type " +
                         std::to_string(subs[sub].type) + ")");
    } else {
      return sub;
    }
    return -1;
  };
  const int ai = pick("ai_subdevice", cfg.ai_subdevice, dev_->default_read_subdevice(), COMEDI_SUBD_AI,
                      SDF_CMD_READ, "analog input");
  const int ao = pick("ao_subdevice", cfg.ao_subdevice, dev_->default_write_subdevice(), COMEDI_SUBD_AO,
                      SDF_CMD_WRITE, "analog output");
  if (ai < 0 || ao < 0) throw std::runtime_error(join(problems));
  ai_sub_ = static_cast<unsigned>(ai);
  ao_sub_ = static_cast<unsigned>(ao);
  const ComediSubdevice& ais = subs[ai_sub_];
  const ComediSubdevice& aos = subs[ao_sub_];

  auto check_chan = [&](const std::string& key, std::int32_t ch, const ComediSubdevice& s) {
    if (ch >= static_cast<std::int32_t>(s.n_chan)) {
      problems.push_back("comedi." + key + ": " + std::to_string(ch) + " is outside [0, " +
                         std::to_string(s.n_chan - 1) + "], the channels of subdevice " +
                         std::to_string(&s == &ais ? ai_sub_ : ao_sub_) + " of " + who);
    }
  };
  for (std::size_t i = 0; i < cfg.detector_channels.size(); ++i) {
    check_chan("detector_channels[" + std::to_string(i) + "]", cfg.detector_channels[i], ais);
  }
  check_chan("x_channel", cfg.x_channel, aos);
  check_chan("y_channel", cfg.y_channel, aos);
  auto check_range = [&](const char* key, std::int32_t r, const ComediSubdevice& s) -> const comedi_krange* {
    if (s.ranges.empty()) {
      problems.push_back(std::string("comedi.") + key + ": " + who +
                         " has per-channel range tables, which sempose does not read");
      return nullptr;
    }
    if (r >= static_cast<std::int32_t>(s.ranges.size())) {
      problems.push_back(std::string("comedi.") + key + ": " + std::to_string(r) + " is outside [0, " +
                         std::to_string(s.ranges.size() - 1) + "], the ranges of " + who);
      return nullptr;
    }
    return &s.ranges[static_cast<std::size_t>(r)];
  };
  const comedi_krange* air = check_range("ai_range", cfg.ai_range, ais);
  const comedi_krange* aor = check_range("ao_range", cfg.ao_range, aos);
  if (aor != nullptr) {
    auto inside = [&](const char* key, const std::vector<double>& v) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (v[i] < range_lo(*aor) || v[i] > range_hi(*aor)) {
          problems.push_back(std::string("comedi.") + key + "[" + std::to_string(i) + "]: " + fmt_v(v[i]) +
                             " V is outside the AO range [" + fmt_v(range_lo(*aor)) + ", " + fmt_v(range_hi(*aor)) +
                             "] V (comedi.ao_range " + std::to_string(cfg.ao_range) + " of " + who + ")");
        }
      }
    };
    inside("x_volts", cfg.x_volts);
    inside("y_volts", cfg.y_volts);
    inside("park_volts", cfg.park_volts);
  }
  if (ais.maxdata == 0 || aos.maxdata == 0) problems.push_back("comedi: " + who + " has per-channel maxdata");
  if (!problems.empty()) throw std::runtime_error(join(problems));

  dev_->select_read_subdevice(ai_sub_);
  dev_->select_write_subdevice(ao_sub_);
  ai_lsampl_ = ais.lsampl();
  ao_lsampl_ = aos.lsampl();
  ai_sample_bytes_ = ais.bytes_per_sample();

  // Field calibration -> AO code per column/row, clamped to the card's codes.
  auto table = [&](const std::vector<double>& volts, std::int32_t n) {
    std::vector<std::uint32_t> codes(static_cast<std::size_t>(n));
    for (std::int32_t i = 0; i < n; ++i) {
      const double v = volts[0] + (volts[1] - volts[0]) * i / std::max(1, n - 1);
      codes[static_cast<std::size_t>(i)] = clamp_code(code_of(v, *aor, aos.maxdata), aos.maxdata);
    }
    return codes;
  };
  park_x_ = clamp_code(code_of(cfg.park_volts[0], *aor, aos.maxdata), aos.maxdata);
  park_y_ = clamp_code(code_of(cfg.park_volts[1], *aor, aos.maxdata), aos.maxdata);
  shape_ = RasterShape{cfg.settle_samples, cfg.flyback_samples, cfg.oversample};
  writer_ = std::make_unique<RasterWriter>(shape_, table(cfg.x_volts, limits.field_w), table(cfg.y_volts, limits.field_h));
  const double black = cfg.detector_volts.empty() ? 0.0 : code_of(cfg.detector_volts[0], *air, ais.maxdata);
  const double white = cfg.detector_volts.empty() ? ais.maxdata : code_of(cfg.detector_volts[1], *air, ais.maxdata);
  const auto n_det = static_cast<std::int32_t>(cfg.detector_channels.size());
  assembler_ = std::make_unique<PixelAssembler>(shape_, n_det, black, white, limits.max_value());

  // Command templates (the per-ROI fields are filled in start()).
  for (std::int32_t i = 0; i < n_det; ++i) {
    ai_chanlist_[i] = CR_PACK(cfg.detector_channels[static_cast<std::size_t>(i)], cfg.ai_range, AREF_GROUND);
  }
  ao_chanlist_[0] = CR_PACK(cfg.x_channel, cfg.ao_range, AREF_GROUND);
  ao_chanlist_[1] = CR_PACK(cfg.y_channel, cfg.ao_range, AREF_GROUND);
  const bool internal = cfg.trigger == "internal";
  ai_cmd_.subdev = ai_sub_;
  ai_cmd_.start_src = internal ? TRIG_NOW : TRIG_INT;
  ai_cmd_.scan_begin_src = TRIG_TIMER;
  ai_cmd_.convert_src = TRIG_NOW;
  ai_cmd_.scan_end_src = TRIG_COUNT;
  ai_cmd_.scan_end_arg = static_cast<unsigned>(n_det);
  ai_cmd_.stop_src = TRIG_COUNT;
  ai_cmd_.stop_arg = 1000;
  ai_cmd_.chanlist = ai_chanlist_;
  ai_cmd_.chanlist_len = static_cast<unsigned>(n_det);
  ao_cmd_.subdev = ao_sub_;
  ao_cmd_.flags = CMDF_WRITE;
  ao_cmd_.start_src = internal ? TRIG_INT : TRIG_EXT;
  ao_cmd_.start_arg = internal ? 0 : cfg.ao_start_arg;
  ao_cmd_.scan_begin_src = TRIG_TIMER;
  ao_cmd_.convert_src = TRIG_NOW;
  ao_cmd_.scan_end_src = TRIG_COUNT;
  ao_cmd_.scan_end_arg = 2;
  ao_cmd_.stop_src = TRIG_COUNT;
  ao_cmd_.stop_arg = 1000;
  ao_cmd_.chanlist = ao_chanlist_;
  ao_cmd_.chanlist_len = 2;

  // What the card can do (COMEDI_CMDTEST): its fastest period and step, for AI and AO.
  Probe pai = probe_period(*dev_, ai_cmd_);
  if (pai.result != 0 && n_det > 1) {  // multi-channel scans may need a convert timer (NI)
    ai_cmd_.convert_src = TRIG_TIMER;
    ai_cmd_.convert_arg = 1;
    comedi_cmd t = ai_cmd_;
    dev_->cmdtest(t);
    ai_cmd_.convert_arg = t.convert_arg;
    timing_.ai_convert_timer = true;
    pai = probe_period(*dev_, ai_cmd_);
  }
  if (pai.result != 0) {
    throw std::runtime_error("comedi.trigger: " + cfg.trigger + ": " + who + " refuses the AI command (start " +
                             (internal ? "TRIG_NOW" : "TRIG_INT") +
                             ", scan_begin TRIG_TIMER, stop TRIG_COUNT; COMEDI_CMDTEST step " +
                             std::to_string(pai.result) + ")");
  }
  const Probe pao = probe_period(*dev_, ao_cmd_);
  if (pao.result != 0) {
    throw std::runtime_error("comedi.trigger: " + cfg.trigger + ": " + who + " refuses the AO command (start " +
                             (internal ? "TRIG_INT" : "TRIG_EXT " + std::to_string(cfg.ao_start_arg)) +
                             ", scan_begin TRIG_TIMER, stop TRIG_COUNT; COMEDI_CMDTEST step " +
                             std::to_string(pao.result) + ")");
  }
  timing_.period_step_ns = std::lcm(pai.step_ns, pao.step_ns);
  const std::uint32_t floor = std::max(pai.min_ns, pao.min_ns);
  timing_.min_period_ns = (floor + timing_.period_step_ns - 1) / timing_.period_step_ns * timing_.period_step_ns;
  const std::uint32_t os = static_cast<std::uint32_t>(cfg.oversample);
  const std::uint64_t dwell_floor = static_cast<std::uint64_t>(timing_.min_period_ns) * os;
  const std::uint64_t dwell_step = static_cast<std::uint64_t>(timing_.period_step_ns) * os;
  if (limits.min_dwell_ns < dwell_floor) {
    problems.push_back("scan.min_dwell_ns: " + std::to_string(limits.min_dwell_ns) + " is below what " + who +
                       " can scan: its fastest AI/AO period with " + std::to_string(n_det) + " detector channel(s) is " +
                       std::to_string(timing_.min_period_ns) + " ns, x comedi.oversample " + std::to_string(os) +
                       " = " + std::to_string(dwell_floor) + " ns per pixel");
  }
  if (limits.dwell_step_ns % dwell_step != 0) {
    problems.push_back("scan.dwell_step_ns: " + std::to_string(limits.dwell_step_ns) +
                       " is not a multiple of the card's period step " + std::to_string(timing_.period_step_ns) +
                       " ns x comedi.oversample " + std::to_string(os) + " = " + std::to_string(dwell_step) + " ns");
  }
  if (!problems.empty()) throw std::runtime_error(join(problems));
  // Line overhead in the scan-time model: settle + flyback scans at the fastest period.
  limits_.line_flyback_ns = static_cast<std::uint32_t>((cfg.settle_samples + cfg.flyback_samples)) * timing_.min_period_ns;

  // Buffers large enough for a full-field scan, so a sleeping poller can never overrun them
  // and the whole raster is written at arming.
  const std::int64_t full = shape_.scans(Roi{0, 0, limits.field_w, limits.field_h});
  ai_buf_ = static_cast<const unsigned char*>(
      dev_->map_buffer(ai_sub_, static_cast<std::size_t>(full) * n_det * ai_sample_bytes_, false, ai_buf_bytes_));
  ao_buf_ = static_cast<unsigned char*>(
      dev_->map_buffer(ao_sub_, static_cast<std::size_t>(full) * 2 * aos.bytes_per_sample(), true, ao_buf_bytes_));
  dev_->cancel(ai_sub_);
  dev_->cancel(ao_sub_);
  park();

  description_ = who + ": AI subdevice " + std::to_string(ai_sub_) + " channel(s)";
  for (std::int32_t i = 0; i < n_det; ++i) description_ += " " + std::to_string(cfg.detector_channels[static_cast<std::size_t>(i)]);
  description_ += ", AO subdevice " + std::to_string(ao_sub_) + " X " + std::to_string(cfg.x_channel) + " Y " +
                  std::to_string(cfg.y_channel) + ", trigger " + cfg.trigger + ", period >= " +
                  std::to_string(timing_.min_period_ns) + " ns step " + std::to_string(timing_.period_step_ns) +
                  " ns, dwell floor " + std::to_string(dwell_floor) + " ns, buffers AI " +
                  std::to_string(ai_buf_bytes_ / 1024) + " KiB AO " + std::to_string(ao_buf_bytes_ / 1024) + " KiB";
}

ComediScanSource::~ComediScanSource() {
  if (dev_) {
    dev_->cancel(ai_sub_);
    dev_->cancel(ao_sub_);
    park();
  }
}

std::int64_t ComediScanSource::now_ns() const noexcept { return rt::now_ns(); }

bool ComediScanSource::park() noexcept {
  const bool x = dev_->write_single(ao_sub_, ao_chanlist_[0], park_x_);
  const bool y = dev_->write_single(ao_sub_, ao_chanlist_[1], park_y_);
  return x && y;
}

StartResult ComediScanSource::start(const ScanRequest& req, FrameSlot& slot) noexcept {
  if (slot_ != nullptr) return StartResult::kBusy;
  std::uint32_t dwell = 0;
  const StartResult check = check_scan_request(limits_, req, slot.capacity_pixels, dwell);
  if (check != StartResult::kStarted) return check;
  const std::int64_t t_arm = rt::now_ns();
  const std::uint32_t period = dwell / static_cast<std::uint32_t>(shape_.oversample);
  const std::int64_t scans = shape_.scans(req.roi);

  writer_->set_roi(req.roi);
  assembler_->set_roi(req.roi, slot.pixels);
  slot_ = &slot;
  failed_ = false;
  consumed_ = marked_ = 0;
  FrameMeta& m = slot.meta;
  begin_frame_meta(m, req, limits_, dwell, seq_);
  m.truth_count = 0;  // a microscope knows no truth

  // Leftovers of the previous scan: a finished AO command keeps its subdevice busy.
  dev_->cancel(ao_sub_);
  dev_->cancel(ai_sub_);
  ao_cmd_.scan_begin_arg = period;
  ao_cmd_.stop_arg = static_cast<unsigned>(scans);
  ai_cmd_.scan_begin_arg = period;
  ai_cmd_.stop_arg = static_cast<unsigned>(scans);
  bool ok = dev_->command(ao_cmd_);
  // The command reset the buffer: the raster goes in from offset 0 and fits (sized at setup).
  if (ok) {
    const std::size_t bytes = static_cast<std::size_t>(scans) * 2 * (ao_lsampl_ ? 4 : 2);
    if (ao_lsampl_) writer_->fill(reinterpret_cast<std::uint32_t*>(ao_buf_), scans);
    else writer_->fill(reinterpret_cast<std::uint16_t*>(ao_buf_), scans);
    comedi_bufinfo bi{};
    bi.subdevice = ao_sub_;
    bi.bytes_written = static_cast<unsigned>(bytes);
    ok = dev_->bufinfo(bi) && bi.bytes_written == bytes;
  }
  if (ok) ok = dev_->command(ai_cmd_);
  m.t_scan_start_ns = rt::now_ns();
  if (ok) ok = dev_->internal_trigger(cfg_.trigger == "internal" ? ao_sub_ : ai_sub_);
  expected_end_ns_ = m.t_scan_start_ns + scans * static_cast<std::int64_t>(period);
  deadline_ns_ = expected_end_ns_ + static_cast<std::int64_t>(cfg_.timeout_ms) * 1'000'000;
  counters_.last_arm_ns = rt::now_ns() - t_arm;
  if (!ok) {
    ++counters_.arm_errors;
    failed_ = true;  // reported by the next poll() as a bad frame
  }
  return StartResult::kStarted;
}

void ComediScanSource::fail_scan() noexcept {
  dev_->cancel(ai_sub_);
  dev_->cancel(ao_sub_);
  slot_->meta.status = FrameStatus::kBad;
  slot_->meta.t_scan_end_ns = rt::now_ns();
  slot_ = nullptr;
}

void ComediScanSource::cancel() noexcept {
  if (slot_ == nullptr) return;
  ++counters_.cancelled;
  failed_ = true;
  dev_->cancel(ai_sub_);
  dev_->cancel(ao_sub_);
  park();
}

// The AI samples this scan owns are [consumed_, marked_) bytes from the command's start (the
// command reset the buffer, so the ring offset is the count modulo its size).
template <typename Sample>
void ComediScanSource::drain() noexcept {
  while (consumed_ < marked_ && !assembler_->complete()) {
    const std::size_t at = static_cast<std::size_t>(consumed_ % ai_buf_bytes_);
    const std::size_t bytes = std::min<std::size_t>(static_cast<std::size_t>(marked_ - consumed_), ai_buf_bytes_ - at);
    const std::int64_t n = static_cast<std::int64_t>(bytes / sizeof(Sample));
    if (n == 0) break;
    const std::int64_t took = assembler_->consume(reinterpret_cast<const Sample*>(ai_buf_ + at), n);
    consumed_ += static_cast<std::uint64_t>(took) * sizeof(Sample);
    if (took < n) break;
  }
}

// One ioctl: takes everything the driver has made readable. COMEDI_BUFINFO's bytes_read is
// clamped by the kernel to the samples it has finished (munged); buf_write_count can run
// ahead of them while the driver is inside its write (reading by it and marking one call
// later once gave a frame shifted by one sample in the VM, most likely from that). The
// accepted bytes are then read from the mmap'd buffer: freed, but not overwritten, since the
// buffer holds a whole frame.
bool ComediScanSource::drain_available() noexcept {
  comedi_bufinfo bi{};
  bi.subdevice = ai_sub_;
  bi.bytes_read = 0x7fffffffu;
  if (!dev_->bufinfo(bi)) return false;
  marked_ += bi.bytes_read;
  if (ai_lsampl_) drain<std::uint32_t>();
  else drain<std::uint16_t>();
  return true;
}

PollResult ComediScanSource::poll() noexcept {
  if (slot_ == nullptr) return PollResult::kIdle;
  if (failed_) {
    fail_scan();
    return PollResult::kError;
  }
  const std::int64_t before = assembler_->samples_done();
  if (!drain_available()) {  // the kernel refuses BUFINFO once the command ended in an error
    ++counters_.stopped;
    fail_scan();
    return PollResult::kError;
  }
  if (!assembler_->complete() && assembler_->samples_done() == before && rt::now_ns() > expected_end_ns_ &&
      !dev_->running(ai_sub_)) {
    // Stopped early, or it ended between the two ioctls: one more look settles which.
    if (!drain_available() || !assembler_->complete()) {
      ++counters_.stopped;
      fail_scan();
      return PollResult::kError;
    }
  }
  if (assembler_->complete()) {
    slot_->meta.t_scan_end_ns = rt::now_ns();  // the last sample has arrived
    ++seq_;
    ++counters_.scans;
    slot_ = nullptr;
    return PollResult::kDone;
  }
  if (rt::now_ns() > deadline_ns_) {
    ++counters_.timeouts;
    fail_scan();
    return PollResult::kError;
  }
  return PollResult::kBusy;
}

}  // namespace sempose::hal
