# Sourced by the tests/cli scripts that need a short `sempose run` with no hardware and no RT
# privileges: a 320x240 simulated field on the virtual clock, one lamella, status every 100 ms.
# small_run_config POSES_CSV CAN_LOG: prints the YAML.
small_run_config() {
  cat <<YAML
scan: {field_w: 320, field_h: 240, max_roi_w: 128, max_roi_h: 128}
sim:
  clock: virtual
  targets:
    - {texture: {source: lamella}, size: [60, 40], start: [160, 120, 0]}
tracker: {pattern_size_px: 64, roi_size_px: 96}
pipeline: {lock_memory: false, hold_dma_latency: false, stats_period_ms: 100,
           acquisition: {cpu: -1, priority: 0}, correlation: {cpu: -1, priority: 0},
           output: {cpu: -1, priority: 0}, non_rt_cpu: -1}
output: {poses_csv: $1}
can: {log_file: $2}
YAML
}
