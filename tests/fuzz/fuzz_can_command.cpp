// libFuzzer target: the CAN command path. Input bytes are a stream of received frames
// (id 2 bytes, flags, len, 64 data bytes max): they go through a memory channel into the
// CAN pose sink exactly as from a bus; every command it hands on must be well-formed, every
// frame is accounted for (command, bad command or someone else's frame), and the pure
// decoder agrees with the encoder on every frame it accepts.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "sempose/can_output/can_pose_sink.hpp"
#include "sempose/hal/can_memory_channel.hpp"
#include "sempose/ipc/protocol.hpp"

namespace co = sempose::can_output;
namespace hal = sempose::hal;
namespace ipc = sempose::ipc;
namespace pl = sempose::pipeline;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  hal::MemoryCanChannel channel(256, true);
  co::CanSinkOptions options;
  options.max_commands_per_cycle = 64;
  co::CanPoseSink sink(channel, options);
  std::size_t pos = 0, injected = 0;
  while (pos + 4 <= size && injected < 200) {
    hal::CanFrame f;
    f.id = static_cast<std::uint32_t>(data[pos] | (data[pos + 1] << 8)) & 0x7FF;
    if (data[pos + 1] & 0x80) f.id = options.ids.command;  // hit the command id often
    f.flags = data[pos + 2];
    f.len = data[pos + 3];
    pos += 4;
    const std::size_t n = std::min<std::size_t>(std::min<std::size_t>(f.len, 64), size - pos);
    std::memcpy(f.data, data + pos, n);
    pos += n;
    // The pure decoder on its own: accepted frames re-encode to the same bytes.
    ipc::WireCommand w;
    if (ipc::decode_command(f.data, f.len, w) == ipc::CommandCheck::kOk) {
      std::uint8_t again[8];
      ipc::encode_command(w, again);
      if (std::memcmp(again, f.data, 8) != 0) std::abort();
    }
    channel.inject(f);
    ++injected;
  }
  for (int cycle = 0; cycle < 8; ++cycle) sink.service(pl::PipelineStatus{}, cycle * 1'000'000);
  pl::Command c;
  std::uint64_t handed = 0;
  while (sink.next_command(c)) {
    ++handed;
    switch (c.kind) {
      case pl::CommandKind::kSelectPatternSet:
        if (c.arg >= ipc::kMaxPatternSets || !(c.nm_per_px >= 0)) std::abort();
        break;
      case pl::CommandKind::kStart:
      case pl::CommandKind::kStop:
        if (c.arg != 0) std::abort();
        break;
      case pl::CommandKind::kReacquire:
        if (c.target >= ipc::kMaxTargets && c.target != ipc::kAllTargets) std::abort();
        break;
      default:
        std::abort();
    }
  }
  const auto& k = sink.counters();
  const std::uint64_t seen = k.commands_accepted.load() + k.commands_overflowed.load() + k.bad_commands.load() +
                             k.non_command_frames.load();
  if (seen != channel.counters().rx_frames.load() || handed != k.commands_accepted.load()) std::abort();
  return 0;
}
