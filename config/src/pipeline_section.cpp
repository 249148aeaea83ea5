#include <string>

#include "sempose/config/pipeline_config.hpp"

namespace sempose::config {
namespace {

void read_stage(Section& parent, const char* key, StageThreadConfig& c) {
  Section s = parent.child(key);
  s.opt("cpu", c.cpu, -1, 1023);
  s.opt("priority", c.priority, 0, 99);
}

bool power_of_two(std::uint32_t v) { return v != 0 && (v & (v - 1)) == 0; }

}  // namespace

void read_pipeline(Section& s, PipelineConfig& c) {
  s.opt_choice("polling", c.polling, {"sleep", "spin"});
  s.opt("poll_slack_us", c.poll_slack_us, 0u, 100'000u);
  s.opt("idle_sleep_us", c.idle_sleep_us, 1u, 100'000u);
  s.opt("strict_rt", c.strict_rt);
  s.opt("lock_memory", c.lock_memory);
  s.opt("hold_dma_latency", c.hold_dma_latency);
  read_stage(s, "acquisition", c.acquisition);
  read_stage(s, "correlation", c.correlation);
  read_stage(s, "output", c.output);
  s.opt("output_on_correlation_thread", c.output_on_correlation_thread);
  s.opt("non_rt_cpu", c.non_rt_cpu, -1, 1023);
  s.opt("frame_ring", c.frame_ring, 2u, 16u);
  s.opt("pose_ring", c.pose_ring, 2u, 256u);
  s.opt("frame_pool_slots", c.frame_pool_slots, 3u, 64u);
  s.opt_list("schedule", c.schedule, 0, 3);
  s.opt("virtual_compute_ns", c.virtual_compute_ns, 0u, 1'000'000'000u);
  s.opt("stats_period_ms", c.stats_period_ms, 10u, 60'000u);
  if (!power_of_two(c.frame_ring)) {
    s.error("frame_ring", std::to_string(c.frame_ring) + " is not a power of two in [2, 16]");
  }
  if (!power_of_two(c.pose_ring)) {
    s.error("pose_ring", std::to_string(c.pose_ring) + " is not a power of two in [2, 256]");
  }
  // A spinning stage never gives its core away: a lower-priority stage pinned to the same core
  // would only run in the kernel's RT-throttling slack (if any). Sleep polling shares a core.
  if (c.polling == "spin") {
    struct Named {
      const char* name;
      const StageThreadConfig* t;
    };
    const Named stages[] = {{"acquisition", &c.acquisition}, {"correlation", &c.correlation}, {"output", &c.output}};
    const int n = c.output_on_correlation_thread ? 2 : 3;  // output on correlation's thread has no core of its own
    for (int a = 0; a < n; ++a) {
      for (int b = a + 1; b < n; ++b) {
        if (stages[a].t->cpu >= 0 && stages[a].t->cpu == stages[b].t->cpu) {
          s.error("polling", "spin needs a core per stage, but " + std::string(stages[a].name) + " and " +
                                 stages[b].name + " are both on cpu " + std::to_string(stages[a].t->cpu) +
                                 " (the spinning one starves the other): give each its own cpu or use polling: sleep");
        }
      }
    }
  }
  if (c.frame_pool_slots < c.frame_ring + 3) {
    s.error("frame_pool_slots", std::to_string(c.frame_pool_slots) + " is below frame_ring + 3 = " +
                                    std::to_string(c.frame_ring + 3) +
                                    " (one slot scanning, one correlating, one spare)");
  }
}

void read_output(Section& s, OutputConfig& c) {
  s.opt("poses_csv", c.poses_csv);
  s.opt("hist_dir", c.hist_dir);
  s.opt("csv_buffer_poses", c.csv_buffer_poses, 16u, 16'777'216u);
  s.opt("print_status", c.print_status);
  s.opt("keep_previous", c.keep_previous);
}

}  // namespace sempose::config
