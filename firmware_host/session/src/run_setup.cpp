#include "sempose/session/run_setup.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sempose/hal/can_candump_log.hpp"
#include "sempose/hal/source_factory.hpp"
#include "sempose/pose/tracker.hpp"
#include "sempose/rt/memory_room.hpp"

namespace sempose::session {

namespace {
// Who holds the flock that refused us on the file open at fd, from /proc/locks ("N: FLOCK
// ADVISORY WRITE|READ PID MAJ:MIN:INODE 0 EOF", device numbers in hex): a reader's shared lock
// (a backup or log shipper copying the file under `flock -s`) was reported as another writer
// (found probing). Empty when not found.
struct LockHolder {
  long pid = 0;
  bool shared = false;
};
LockHolder lock_holder(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return {};
  std::ifstream locks("/proc/locks");
  for (std::string line; std::getline(locks, line);) {
    std::istringstream in(line);
    std::string n, kind, advisory, mode, dev;
    long pid = 0;
    if (!(in >> n >> kind) || kind != "FLOCK" || !(in >> advisory >> mode >> pid >> dev)) continue;  // "->": a waiter
    unsigned maj = 0, min = 0;
    unsigned long long ino = 0;
    if (std::sscanf(dev.c_str(), "%x:%x:%llu", &maj, &min, &ino) != 3) continue;
    if (maj == major(st.st_dev) && min == minor(st.st_dev) && ino == st.st_ino) return {pid, mode == "READ"};
  }
  return {};
}

// The refusal for a file or folder another process holds a lock on.
rt::Status held_elsewhere(const std::string& what, const std::string& path, int fd, const std::string& writers_clash) {
  const LockHolder h = lock_holder(fd);
  const std::string who = h.pid > 0 ? "process " + std::to_string(h.pid) : "another process";
  if (h.shared) {
    return rt::Status::failure(what + ": '" + path + "' is locked by " + who + " with a reader's shared lock (a backup or " +
                               "log shipper copying it?); it would be emptied under the reader: start again when it is " +
                               "done, or name another file");
  }
  return rt::Status::failure(what + ": '" + path + "' is being written by another process (" +
                             (h.pid > 0 ? who : std::string("it")) + " holds a lock on it: another sempose run or replay); " +
                             writers_clash);
}
}  // namespace

OutputLock::~OutputLock() {
  if (fd_ >= 0) ::close(fd_);
}

bool OutputLock::empty_file() const noexcept { return fd_ < 0 || ::ftruncate(fd_, 0) == 0; }

rt::Status OutputLock::acquire(const std::string& what, const std::string& path) {
  if (path.empty() || path == "-") return {};
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) return {};  // a device: nothing to mix up
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return rt::Status::failure(what + ": cannot open '" + path + "' (" + std::strerror(errno) + ")");
  return hold(fd, what, path, "two writers would mix their lines: name another file or stop the other one");
}

rt::Status OutputLock::acquire_folder(const std::string& what, const std::string& path) {
  if (path.empty()) return {};
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  const int fd = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return rt::Status::failure(what + ": cannot open the folder '" + path + "' (" + std::strerror(errno) + ")");
  return hold(fd, what, path, "the two runs' histograms would replace each other: name another folder or stop the other one");
}

rt::Status OutputLock::hold(int fd, const std::string& what, const std::string& path, const std::string& writers_clash) {
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    rt::Status refused = err == EWOULDBLOCK ? held_elsewhere(what, path, fd, writers_clash)
                                            : rt::Status::failure(what + ": cannot lock '" + path + "' (" + std::strerror(err) + ")");
    ::close(fd);
    return refused;
  }
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
  return {};
}

rt::Status build_inputs(const config::AppConfig& cfg, RunSetup& out) {
  rt::Status st;
  out.source = hal::make_scan_source(cfg.source, cfg.scan, cfg.sim, cfg.replay, st, cfg.comedi);
  if (!out.source) return rt::Status::failure("scan source: " + st.message);
  out.scan = out.source.get();
  st = can_output::make_frame_sync(cfg.gpio, out.frame_sync);
  if (!st) return rt::Status::failure("gpio: " + st.message);
  if (out.frame_sync) {
    // The edge's kernel time stamp is CLOCK_MONOTONIC: the scan end only on a live clock.
    out.synced = std::make_unique<hal::GpioSyncedSource>(
        *out.source, *out.frame_sync, static_cast<std::int64_t>(cfg.gpio.frame_sync_timeout_us) * 1000,
        !pipeline::uses_virtual_clock(cfg));
    out.scan = out.synced.get();
  }
  out.clock = pipeline::make_stage_clock(cfg);
  if (rt::Status st_trackers = pipeline::make_trackers(cfg, out.scan->limits(), out.trackers);
      !st_trackers)
    return st_trackers;
  // The frame pool is allocated with the pipeline, after the outputs are opened: its size is
  // checked here, with the inputs, against what the trackers' banks left (found probing: 64
  // slots of a 4096² recording under `ulimit -v` failed there as a bare std::bad_alloc; 64 of a
  // 16384² field ask 32 GiB, in range).
  const std::uint64_t pool =
      pipeline::Pipeline::frame_pool_bytes_for(cfg.pipeline, out.scan->limits());
  if (const std::uint64_t room = rt::memory_room().least(); room > 0 && pool > room) {
    const hal::ScanLimits& l = out.scan->limits();
    return rt::Status::failure(
        "the frame pool needs " + std::to_string(pool / 1000000) + " MB, more than the " +
        std::to_string(room / 1000000) + " MB this machine has available: " +
        std::to_string(pipeline::Pipeline::frame_pool_slots_for(cfg.pipeline)) +
        " slots (pipeline.frame_pool_slots) of the " + std::to_string(l.field_w) + "x" +
        std::to_string(l.field_h) + " field at 2 bytes a pixel");
  }
  return rt::Status::success();
}

config::AppConfig replay_config(const config::AppConfig& cfg, const std::string& frames_dir) {
  config::AppConfig out = cfg;
  out.source = "replay";
  out.replay.frames_dir = frames_dir;
  out.replay.clock = "virtual";
  out.replay.loop = false;
  out.gpio.chip.clear();
  return out;
}

rt::Status build_outputs(const config::AppConfig& cfg, const std::string& can_log_override, const std::string& hist_dir,
                         RunSetup& out) {
  // A closed standard output (`sempose run … | head -1`, a reader that went away) must not
  // kill the controller with SIGPIPE (measured: killed by signal 13 at the first status
  // flush; CSV and candump log cut, no summary, CAN output gone): writes to it fail with
  // EPIPE instead, which the CSV writer counts when it writes to "-". systemd services
  // ignore SIGPIPE by default (IgnoreSIGPIPE=yes): the same behaviour from a shell.
  // (`sempose replay` does not call this and keeps SIGPIPE: a filter ends with its reader.)
  ::signal(SIGPIPE, SIG_IGN);
  // Output files may name folders that do not exist yet (out/demo/...): made now, after every
  // check and the input setup, so a refused run leaves nothing behind.
  // The folders made here are removed again when the run is refused (CAN, GPIO, a lock, the
  // pipeline's memory): a refused run used to leave them (hostile round 8).
  const std::string can_log = can_log_override.empty() && cfg.can.interface.empty() ? cfg.can.log_file : can_log_override;
  for (const std::string& file : {cfg.output.poses_csv, can_log}) {
    const auto parent = std::filesystem::path(file).parent_path();
    std::error_code ec;
    if (!file.empty() && file != "-" && !parent.empty()) out.made_folders.make(parent, ec);
  }
  if (!hist_dir.empty()) {
    std::error_code ec;
    out.made_folders.make(hist_dir, ec);  // acquire_folder below names a folder it cannot open
  }
  // Each output file is locked just before it is opened for writing (and truncated): a second
  // run on the same file stops here, naming it, and the first one's lines stay as they are.
  auto lock = [&out](const std::string& what, const std::string& file) {
    OutputLock l;
    rt::Status locked = l.acquire(what, file);
    if (locked) out.output_locks.push_back(std::move(l));
    return locked;
  };
  // Both locked before either is opened, and both opened before either is emptied: a run refused
  // on the second, or on anything after, must not have emptied the first (found probing: a run
  // refused on a poses CSV another run was writing had already truncated its own CAN log, and so
  // had one whose CSV could not be opened for want of a file descriptor). A file that did not
  // exist before the run is removed again when the run is refused.
  const auto exists = [](const std::string& f) {
    struct stat st {};
    return !f.empty() && f != "-" && ::stat(f.c_str(), &st) == 0;
  };
  const bool log_existed = exists(can_log), csv_existed = exists(cfg.output.poses_csv);
  const auto refuse = [&](rt::Status st) {
    out.csv.reset();
    out.can.sink.reset();  // before the channel it sends on
    out.can.channel.reset();
    if (!log_existed && exists(can_log)) ::unlink(can_log.c_str());
    if (!csv_existed && exists(cfg.output.poses_csv)) ::unlink(cfg.output.poses_csv.c_str());
    out.output_locks.clear();  // the histogram folder's lock holds it open
    out.made_folders.remove_empty();
    return st;
  };
  // Memory that runs out anywhere below (the CAN and CSV writers' buffers, under `ulimit -v`)
  // refuses the run as any other failure here: it escaped to main as a bare "out of memory" and
  // left the 0-byte CSV and candump log it had created, and their folder (hostile round 10).
  // A bare "std::bad_alloc" named nothing either (found probing the pipeline's allocation).
  const char* allocating = "opening the outputs";
  try {
    const std::size_t log_lock = out.output_locks.size();
    if (rt::Status locked = lock(can_log_override.empty() ? "can.log_file" : "--can-log", can_log); !locked) return refuse(locked);
    if (rt::Status locked = lock("output.poses_csv", cfg.output.poses_csv); !locked) return refuse(locked);
    if (!hist_dir.empty()) {
      OutputLock folder;
      if (rt::Status locked = folder.acquire_folder("histograms", hist_dir); !locked) return refuse(locked);
      out.output_locks.push_back(std::move(folder));
    }
    rt::Status st = can_output::make_can_output(cfg.can, can_log_override, out.can, true);
    if (!st) return refuse(rt::Status::failure("can: " + st.message));
    st = can_output::make_gpio_outputs(cfg.gpio, out.gpio_out);
    if (!st) return refuse(rt::Status::failure("gpio: " + st.message));
    if (!cfg.output.poses_csv.empty()) {
      out.csv = std::make_unique<pipeline::CsvPoseSink>(cfg.output.poses_csv, cfg.output.csv_buffer_poses,
                                                        out.trackers.trackers.size() > 1);
      st = out.csv->open_keeping();
      if (!st) return refuse(st);
    }
    out.sink = out.can.sink.get();
    if (out.csv) {
      out.tee = std::make_unique<pipeline::TeePoseSink>(out.can.sink.get(), out.csv.get());
      out.sink = out.tee.get();
    }
    if (out.gpio_out) {
      out.gpio_sink = std::make_unique<can_output::GpioPoseSink>(*out.sink, *out.gpio_out);
      out.sink = out.gpio_sink.get();
    }
    std::vector<pose::Tracker*> raw;
    for (auto& t : out.trackers.trackers) raw.push_back(t.get());
    // Its frame pool is what most often does not fit (said so when memory runs out there).
    allocating = "allocating the pipeline (its frame pool: pipeline.frame_pool_slots full-field frames)";
    out.pipeline = std::make_unique<pipeline::Pipeline>(cfg.pipeline, cfg.governor, *out.scan, raw, *out.sink, *out.clock);
    allocating = "opening the outputs";
    // output.keep_previous: the last run's files kept as NAME.1 before they are emptied (a unit
    // restarted after a watchdog kill or a crash erased the record of the run that failed, 2 s
    // later; found probing). A copy, so the locks and open files stay on the outputs themselves. A
    // copy that fails is said and the run goes on: the new run's poses matter more than the old.
    if (cfg.output.keep_previous) {
      for (const std::string& file : {can_log, cfg.output.poses_csv}) {
        struct stat last {};
        if (file.empty() || file == "-" || ::stat(file.c_str(), &last) != 0 || !S_ISREG(last.st_mode) || last.st_size == 0) continue;
        std::error_code ec;
        std::filesystem::copy_file(file, file + ".1", std::filesystem::copy_options::overwrite_existing, ec);
        out.output_notes.push_back(ec ? "warning: output.keep_previous: the last run's " + file + " could not be kept as " + file +
                                            ".1 (" + ec.message() + "): it is emptied now"
                                      : "output.keep_previous: the last run's " + file + " kept as " + file + ".1");
      }
    }
    // Every output open: now the candump log (a regular file; SocketCAN has none) and the CSV are
    // emptied, and the CSV's header written.
    if (!out.output_locks[log_lock].empty_file())
      return rt::Status::failure(std::string(can_log_override.empty() ? "can.log_file" : "--can-log") + " '" + can_log +
                                 "': cannot empty it: " + std::strerror(errno));
    if (out.csv) return out.csv->begin();
    return rt::Status::success();
  } catch (const std::exception& e) {
    out.pipeline.reset();
    out.sink = nullptr;
    out.tee.reset();
    out.gpio_sink.reset();
    const bool oom = dynamic_cast<const std::bad_alloc*>(&e) != nullptr;
    return refuse(rt::Status::failure(oom ? std::string("out of memory ") + allocating +
                                                " (the machine's memory, or an address-space limit: ulimit -v, RLIMIT_AS)"
                                          : e.what()));
  }
}

namespace {
const hal::CandumpLogChannel* candump_of(const RunSetup& s) {
  return dynamic_cast<const hal::CandumpLogChannel*>(s.can.channel.get());
}
}  // namespace

std::uint64_t RunSetup::output_write_errors() const {
  const auto* candump = candump_of(*this);
  return (csv ? csv->write_errors() : 0) + (candump ? candump->write_errors() : 0);
}

bool RunSetup::output_ring_overflowed() const {
  const auto* candump = candump_of(*this);
  return (csv && csv->dropped() > 0) || (candump && candump->bytes_dropped_ring_full() > 0);
}

int RunSetup::last_output_errno() const {
  const auto* candump = candump_of(*this);
  return csv && csv->last_errno() ? csv->last_errno() : candump ? candump->last_errno() : 0;
}

void RunSetup::flush_outputs() {
  if (csv) csv->write_pending();
  if (can.sink) can.sink->flush();
}

}  // namespace sempose::session
