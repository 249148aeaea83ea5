#!/usr/bin/python3
"""Host-side checks of the sempose system test (run_system_test.sh, run_native.sh).

check_results.py --artifacts DIR [--dbc ipc/sempose.dbc] [--duration S] [--report FILE]

Reads what the target side (guest/guest_test.sh) left in DIR: results.txt (its CHECK lines),
candump.log (candump -L on the bus during `sempose run`), sempose_stdout.txt (placements,
summary line), poses.csv (sempose's own record), commands_sent.txt, gpio_outputs.txt,
sempose_threads.txt (/proc/PID/task/*/stat), sempose_status.txt, sync_edges.txt,
cyclictest_hist.txt and sempose's latency_hist.{txt,json}. Frames are read with python-can's
CanutilsLogReader and decoded with ipc/tools/sempose_dbc.py (the project's DBC decoder).
Prints one line per check and RESULT; exit 0 when nothing failed.
"""
import argparse
import csv
import io
import json
import os
import re
import sys

SRC = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(SRC, "ipc", "tools"))
from sempose_dbc import Dbc  # noqa: E402

PASS, FAIL, SKIP = "PASS", "FAIL", "SKIP"
# Target-side checks that must all have passed (the infrastructure and the sempose run).
TARGET_CHECKS = ["preempt_rt", "can_if", "gpio_sim", "can_selfcheck", "gpio_input", "gpio_output", "gpio_edge",
                 "can_gpio_hw_test", "cyclictest", "sempose_can_bound", "sempose_gpio_requested",
                 "cmd_select", "cmd_reacquire", "cmd_malformed", "sempose_exit", "check_rt",
                 "comedi_devices", "comedi_hw_test", "comedi_run", "can_rebind"]
BASE = 0x100
ID_XY, ID_ATTR, ID_HB, ID_CMD = BASE + 0x00, BASE + 0x01, BASE + 0x40, BASE + 0x50
SCALES_NM_PER_PX = (40.0, 20.0)   # system.yaml: pattern set 0 and 1
NM_PER_PX_COMEDI = 40.0          # system_comedi.yaml
REASON_BAD_FRAME = 16             # LostReason bit: the frame was flagged bad (e.g. no frame-sync edge)


class Ctx:
    def __init__(self, art, dbc_path, duration):
        self.art, self.duration = art, duration
        self.db = Dbc.load(dbc_path)
        self.target = {}
        for line in self.read("results.txt").splitlines():
            m = re.match(r"CHECK (\S+) (PASS|FAIL|SKIP) ?(.*)", line)
            if m:
                self.target[m.group(1)] = (m.group(2), m.group(3))
        self.stdout = self.read("sempose_stdout.txt")
        self.summary = {}
        for line in reversed(self.stdout.splitlines()):
            if line.startswith("summary:"):
                self.summary = dict(re.findall(r"(\w+)=(\S+)", line))
                break
        self.frames = self.load_log("candump.log")   # [(t, id, bytes)]
        self.decoded = {}                            # id -> [(t, signals)]
        self.undecodable = []
        for t, i, d in self.frames or []:
            name, sig = self.db.decode(i, d)
            if name is None:
                self.undecodable.append((t, i, d))
            else:
                self.decoded.setdefault(i, []).append((t, sig))
        self.sent = []                               # [(label, frame)]
        for line in self.read("commands_sent.txt").splitlines():
            p = line.split()
            if len(p) >= 3 and "SEND-FAILED" not in line:
                self.sent.append((p[1], p[2]))

    def path(self, name):
        return os.path.join(self.art, name)

    def read(self, name):
        try:
            with open(self.path(name), encoding="utf-8", errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def load_log(self, name):
        if not os.path.isfile(self.path(name)):
            return None
        import can  # python3-can
        out = []
        try:
            for msg in can.CanutilsLogReader(self.path(name)):
                if not (msg.is_error_frame or msg.is_remote_frame):
                    out.append((msg.timestamp, msg.arbitration_id, bytes(msg.data)))
        except Exception as e:  # a torn last line: keep what was read
            print(f"warning: {name}: {e}", file=sys.stderr)
        return out

    def num(self, key):
        try:
            return float(self.summary[key])
        except (KeyError, ValueError):
            return None

    def command_time(self, label):
        """candump timestamp of an injected command frame (it is on the bus too)."""
        frame = dict(self.sent).get(label)
        if frame is None or self.frames is None:
            return None
        want = bytes.fromhex(frame.split("#", 1)[1])
        for t, i, d in self.frames:
            if i == ID_CMD and d == want:
                return t
        return None


def need_run(ctx):
    if not ctx.summary:
        st = ctx.target.get("sempose_exit", (FAIL, "not recorded"))
        return FAIL, f"no summary line from sempose ({st[1][:200]})"
    if ctx.frames is None:
        return FAIL, "no candump.log"
    return None


# ---------------------------------------------------------------------------- checks
def check_target_side(ctx):
    bad = [f"{n}: {ctx.target[n][1][:160]}" for n in TARGET_CHECKS if n in ctx.target and ctx.target[n][0] == FAIL]
    missing = [n for n in TARGET_CHECKS if n not in ctx.target]
    if bad or missing:
        return FAIL, "; ".join(bad) + (f" (not recorded: {' '.join(missing)})" if missing else "")
    skipped = [n for n in TARGET_CHECKS if ctx.target[n][0] == SKIP]
    return PASS, (f"{len(TARGET_CHECKS)} target checks passed (PREEMPT_RT, CAN loop, gpio in/out/edge, "
                  f"can_gpio_hw_test, commands acknowledged, Comedi devices, comedi_hw_test, comedi run, CAN re-bind)" + (f"; skipped: {skipped}" if skipped else ""))


def check_summary(ctx):
    r = need_run(ctx)
    if r:
        return r
    want = ["poses", "poses_per_s", "tracked_share", "dropped", "overruns", "rt_allocs", "e2e_us_p50",
            "e2e_us_p99", "e2e_us_p999", "e2e_us_max", "dwell_ns_min", "dwell_ns_max", "frames", "scan_errors",
            "can_sent", "can_dropped", "can_bad_commands", "commands", "duration_s"]
    missing = [k for k in want if ctx.num(k) is None]
    if missing:
        return FAIL, f"summary lacks or garbles {missing}"
    problems = []
    if ctx.num("poses") <= 0:
        problems.append("poses=0")
    if ctx.num("rt_allocs") != 0:
        problems.append(f"rt_allocs={ctx.summary['rt_allocs']} (heap calls on RT threads)")
    # the target side stops sempose with SIGTERM after the commands, >= duration s
    if ctx.num("duration_s") < ctx.duration - 1.0:
        problems.append(f"duration_s={ctx.summary['duration_s']} < {ctx.duration}")
    if "stopped by SIGTERM" not in ctx.stdout:
        problems.append("no 'stopped by SIGTERM' (sempose ended on its own)")
    if ctx.num("commands") != 2:
        problems.append(f"commands={ctx.summary['commands']} (2 valid commands were sent)")
    if ctx.num("can_sent") + ctx.num("can_dropped") != ctx.num("poses"):
        problems.append(f"can_sent+can_dropped={ctx.num('can_sent') + ctx.num('can_dropped'):g} != poses")
    if not 0 < ctx.num("tracked_share") <= 1:
        problems.append(f"tracked_share={ctx.summary['tracked_share']}")
    d = " ".join(f"{k}={ctx.summary[k]}" for k in want if k not in ("e2e_us_p50", "e2e_us_p999"))
    return (FAIL, "; ".join(problems) + " | " + d) if problems else (PASS, d)


def check_rt_setup(ctx):
    """What a user of an RT controller expects: SCHED_FIFO threads where configured, pinned,
    memory locked, no degradation warnings."""
    r = need_run(ctx)
    if r:
        return r
    problems, details = [], []
    placements = dict(re.findall(r"^thread (\w+): (.*)$", ctx.stdout, re.M))
    for name, want in (("acquisition", "SCHED_FIFO 60 on cpu 0"), ("correlation", "SCHED_FIFO 50 on cpu 1")):
        got = placements.get(name)
        if got != want:
            problems.append(f"{name}: '{got}' (config: {want})")
    details.append("placements " + "; ".join(f"{k}: {v}" for k, v in placements.items()))
    warnings = re.findall(r"^warning: (.*)$", ctx.stdout, re.M)
    if warnings:
        problems.append(f"sempose warned: {warnings[:3]}")
    # The kernel's view: /proc/PID/task/TID/stat fields 40 (rt_priority), 41 (policy), 39 (cpu).
    fifo = []
    for line in ctx.read("sempose_threads.txt").splitlines():
        m = re.match(r"(\d+) \((.*)\) (.*)", line)
        if not m:
            continue
        rest = m.group(3).split()
        prio, policy, cpu = int(rest[37]), int(rest[38]), int(rest[36])
        if policy == 1:  # SCHED_FIFO
            fifo.append((m.group(2), prio, cpu))
    prios = sorted(p for _, p, _ in fifo)
    if not set([50, 60]) <= set(prios):
        problems.append(f"kernel shows SCHED_FIFO threads {fifo} (want priorities 60 and 50)")
    details.append("kernel: " + ", ".join(f"{c} FIFO {p} cpu{cpu}" for c, p, cpu in fifo))
    lck = re.search(r"VmLck:\s*(\d+) kB", ctx.read("sempose_status.txt"))
    if not lck or int(lck.group(1)) == 0:
        problems.append(f"no locked memory (VmLck {lck.group(1) if lck else '?'} kB)")
    else:
        details.append(f"VmLck {int(lck.group(1)) // 1024} MiB")
    return (FAIL, "; ".join(problems)) if problems else (PASS, "; ".join(details))


def check_pose_frames(ctx):
    """Pose frames on the bus: one XY + one ATTR per pose, all of sempose's poses, at its rate."""
    r = need_run(ctx)
    if r:
        return r
    xy, attr = ctx.decoded.get(ID_XY, []), ctx.decoded.get(ID_ATTR, [])
    if not xy or not attr:
        return FAIL, f"no POSE_XY_T0/POSE_ATTR_T0 frames on the bus ({len(ctx.frames)} frames in all)"
    problems = []
    sent = ctx.num("can_sent")
    if len(xy) != sent or len(attr) != sent:
        problems.append(f"{len(xy)} XY / {len(attr)} ATTR frames but can_sent={sent:g}")
    span = xy[-1][0] - xy[0][0]
    rate = (len(xy) - 1) / span if span > 0 else 0.0
    claimed = ctx.num("poses_per_s")
    # the first pose comes after the full-field start search: the bus rate is a bit higher
    if not 0.8 * claimed <= rate <= 1.5 * claimed:
        problems.append(f"bus rate {rate:.1f}/s vs summary poses_per_s={claimed}")
    # Under TCG a pose costs 10-100x its native time and the host may be busy: the rate is a
    # functional check (poses keep flowing), not a performance figure.
    if rate < 2:
        problems.append(f"bus rate {rate:.1f} poses/s < 2")
    # (the injected malformed command is undecodable on purpose: checked in `commands`)
    foreign = [hex(i) for _, i, _ in ctx.undecodable if i != ID_CMD]
    if foreign:
        problems.append(f"frames the DBC does not know: {sorted(set(foreign))[:5]}")
    d = f"{len(xy)} POSE_XY_T0 + {len(attr)} POSE_ATTR_T0 frames at {rate:.1f}/s over {span:.1f} s (summary {claimed}/s)"
    return (FAIL, "; ".join(problems) + " | " + d) if problems else (PASS, d)


def check_sequence(ctx):
    r = need_run(ctx)
    if r:
        return r
    allowed = int(ctx.num("can_dropped") or 0)
    details, problems = [], []
    seqs = {}
    for fid, name in ((ID_XY, "POSE_XY_T0"), (ID_ATTR, "POSE_ATTR_T0")):
        vals = [int(s["seq"]) for _, s in ctx.decoded.get(fid, [])]
        if not vals:
            problems.append(f"no {name} frames")
            continue
        seqs[name] = vals
        gaps = [(a, b) for a, b in zip(vals, vals[1:]) if (b - a) % 256 != 1]
        missing = sum(((b - a) % 256) - 1 for a, b in gaps)
        details.append(f"{name}.seq: {len(vals)} values, {len(gaps)} gaps ({missing} missing)")
        if missing > allowed:
            problems.append(f"{name}: {missing} missing > counted drops {allowed}; first gaps {gaps[:5]}")
        if vals[0] != 0:
            problems.append(f"{name}: first seq {vals[0]} (poses before it were not on the bus)")
    if len(seqs) == 2 and seqs["POSE_XY_T0"] != seqs["POSE_ATTR_T0"]:
        problems.append("XY and ATTR frames do not pair up by seq")
    hb = [int(s["counter"]) for _, s in ctx.decoded.get(ID_HB, [])]
    hb_gaps = sum(1 for a, b in zip(hb, hb[1:]) if (b - a) % 256 != 1)
    details.append(f"HEARTBEAT.counter: {len(hb)} values, {hb_gaps} gaps")
    if hb_gaps:
        problems.append(f"heartbeat counter has {hb_gaps} gaps")
    return (FAIL, "; ".join(problems)) if problems else (PASS, "; ".join(details) + f" (counted drops {allowed})")


def _csv_rows(ctx):
    try:
        with open(ctx.path("poses.csv"), newline="") as f:
            return list(csv.DictReader(f))
    except OSError:
        return None


def check_values_vs_csv(ctx):
    """Every pose on the bus is the pose sempose wrote to poses.csv: x/y in nm at the active
    pattern set's scale (40 nm/px, 20 after SELECT_PATTERN_SET 1), phi, score, state."""
    r = need_run(ctx)
    if r:
        return r
    rows = _csv_rows(ctx)
    if rows is None:
        return FAIL, "no poses.csv (config output.poses_csv)"
    xy, attr = ctx.decoded.get(ID_XY, []), ctx.decoded.get(ID_ATTR, [])
    if len(rows) != len(xy) or len(xy) != len(attr):
        return FAIL, f"{len(rows)} CSV rows vs {len(xy)} XY / {len(attr)} ATTR frames (can_dropped={ctx.summary.get('can_dropped')})"
    t_select = ctx.command_time("select")
    bad, scales = [], []
    states = {0: "TRACKING", 1: "ACQUIRING", 2: "LOST", 3: "UNCERTAIN"}
    for k, (row, (t, sxy), (_, sat)) in enumerate(zip(rows, xy, attr)):
        px, py = float(row["x_px"]), float(row["y_px"])
        fit = [s for s in SCALES_NM_PER_PX
               if abs(sxy["x"] - round(px * s)) <= 1 + 0.01 * s and abs(sxy["y"] - round(py * s)) <= 1 + 0.01 * s]
        if not fit:
            bad.append(f"pose {k}: x,y=({sxy['x']:g},{sxy['y']:g}) nm vs ({px},{py}) px")
        else:
            scales.append((t, fit[0]))
        if abs(sat["phi"] - float(row["phi_deg"])) > 0.0011:
            bad.append(f"pose {k}: phi {sat['phi']:.3f} vs {row['phi_deg']}")
        if abs(sat["score"] - float(row["score"])) > 0.0011:
            bad.append(f"pose {k}: score {sat['score']:.3f} vs {row['score']}")
        if states.get(int(sat["state"])) != row["status"].strip():
            bad.append(f"pose {k}: state {sat['state']:g} vs {row['status']}")
    # the scale switches once, from 40 to 20 nm/px, after the select command (never before)
    switches = [(a, b) for a, b in zip(scales, scales[1:]) if a[1] != b[1]]
    if [(a[1], b[1]) for a, b in switches] != [(40.0, 20.0)]:
        bad.append(f"scale changes {[(a[1], b[1]) for a, b in switches]} (want one 40 -> 20 after the select)")
    elif t_select is None or switches[0][1][0] < t_select:
        bad.append("the scale changed before the select command was on the bus")
    d = f"{len(rows)} poses identical on the bus and in poses.csv (x/y nm, phi, score, state)"
    if switches:
        d += f"; scale 40 -> 20 nm/px {switches[0][1][0] - (t_select or 0):.3f} s after SELECT_PATTERN_SET 1"
    return (FAIL, f"{len(bad)} mismatches, first: {bad[:4]}") if bad else (PASS, d)


def check_heartbeat(ctx):
    r = need_run(ctx)
    if r:
        return r
    hb = ctx.decoded.get(ID_HB, [])
    m = re.search(r"heartbeat_hz:\s*([0-9.]+)", ctx.read("system.yaml"))
    hz = float(m.group(1)) if m else 10.0
    if len(hb) < 2:
        return FAIL, f"{len(hb)} HEARTBEAT frames"
    span = hb[-1][0] - hb[0][0]
    rate = (len(hb) - 1) / span
    expect = hz * ctx.num("duration_s")
    problems = []
    # The heartbeat is serviced between poses on the correlation thread; under TCG one pose
    # can take 100+ ms, so only a grossly wrong rate (or a burst above it) fails.
    if not 0.5 * hz <= rate <= 1.2 * hz:
        problems.append(f"rate {rate:.2f}/s vs can.heartbeat_hz {hz:g}")
    if len(hb) < 0.5 * expect:
        problems.append(f"{len(hb)} heartbeats, expected ~{expect:.0f}")
    last = hb[-1][1]
    if last["bus_state"] != 0 or last["running"] != 1:
        problems.append(f"last heartbeat bus_state={last['bus_state']:g} running={last['running']:g}")
    d = f"{len(hb)} HEARTBEAT frames at {rate:.2f}/s (config {hz:g} Hz), bus ERROR_ACTIVE, running"
    return (FAIL, "; ".join(problems) + " | " + d) if problems else (PASS, d)


def check_commands(ctx):
    """SELECT_PATTERN_SET 1 (seq 1), REACQUIRE all (seq 2), then a malformed 4-byte command:
    acknowledged/counted in the following heartbeats, the malformed one ignored."""
    r = need_run(ctx)
    if r:
        return r
    labels = [l for l, _ in ctx.sent]
    if labels != ["select", "reacquire", "malformed"]:
        return FAIL, f"commands sent: {ctx.sent} (want select, reacquire, malformed)"
    # what the frames mean according to the DBC
    sel = ctx.db.decode(ID_CMD, bytes.fromhex(dict(ctx.sent)["select"].split("#")[1]))
    acq = ctx.db.decode(ID_CMD, bytes.fromhex(dict(ctx.sent)["reacquire"].split("#")[1]))
    mal = ctx.db.decode(ID_CMD, bytes.fromhex(dict(ctx.sent)["malformed"].split("#")[1]))
    problems, details = [], []
    if sel[0] != "COMMAND" or (sel[1]["opcode"], sel[1]["seq"], sel[1]["arg"]) != (1, 1, 1):
        problems.append(f"select frame decodes as {sel}")
    if acq[0] != "COMMAND" or (acq[1]["opcode"], acq[1]["seq"], acq[1]["arg"]) != (4, 2, 255):
        problems.append(f"reacquire frame decodes as {acq}")
    if mal[0] is not None:
        problems.append(f"the malformed frame decodes as a valid {mal[0]}")
    times = {l: ctx.command_time(l) for l in labels}
    if None in times.values():
        return FAIL, f"command frames not seen on the bus: {[l for l, t in times.items() if t is None]}"
    hb = ctx.decoded.get(ID_HB, [])

    def hb_after(t):
        return [s for th, s in hb if th > t]
    before = [s for th, s in hb if th < times["select"]]
    if any(s["pattern_set"] != 0 or s["bad_commands"] != 0 for s in before):
        problems.append("heartbeat showed pattern_set/bad_commands != 0 before any command")
    after_sel = hb_after(times["select"])
    first = next((i for i, s in enumerate(after_sel) if s["pattern_set"] == 1 and s["last_command_seq"] == 1), None)
    if first is None:
        problems.append("no heartbeat with pattern_set=1, last_command_seq=1 after SELECT_PATTERN_SET 1")
    else:
        details.append(f"select -> HEARTBEAT pattern_set=1 last_command_seq=1 ({first + 1}. heartbeat after)")
        if any(s["pattern_set"] != 1 for s in after_sel[first:]):
            problems.append("pattern_set fell back from 1")
    after_acq = hb_after(times["reacquire"])
    if not any(s["last_command_seq"] == 2 for s in after_acq):
        problems.append("no heartbeat with last_command_seq=2 after REACQUIRE")
    else:
        details.append("reacquire -> last_command_seq=2")
    # The command's effect in the pose stream: a pose with reason 32 (commanded) that is not
    # TRACKING — ACQUIRING on the ROI frame in flight, or the search's own pose, UNCERTAIN
    # until the next frame confirms it, when the search ran on the first frame after it.
    attr_after = [s for t, s in ctx.decoded.get(ID_ATTR, []) if t > times["reacquire"]][:50]
    reacq = [s for s in attr_after if s["state"] != 0 and int(s["reason"]) & 32]
    if not reacq:
        before_acq = [s["state"] for t, s in ctx.decoded.get(ID_ATTR, []) if t < times["reacquire"]]
        problems.append("no pose with reason 32 (commanded) in the 50 poses after REACQUIRE (state/reason "
                        f"{[(int(s['state']), int(s['reason'])) for s in attr_after[:10]]}; "
                        f"{'no TRACKING pose before it' if 0 not in before_acq else 'last state before it ' + str(before_acq[-1])})")
    else:
        s = reacq[0]
        details.append(f"a following pose is {('TRACKING', 'ACQUIRING', 'LOST', 'UNCERTAIN')[int(s['state'])]} "
                       f"(reason {int(s['reason'])})")
    after_mal = hb_after(times["malformed"])
    if not after_mal or after_mal[-1]["bad_commands"] != 1 or after_mal[-1]["last_command_seq"] != 2:
        problems.append("after the malformed command the heartbeat does not show bad_commands=1 with "
                        f"last_command_seq still 2 ({after_mal[-1] if after_mal else 'no heartbeat'})")
    else:
        details.append("malformed -> bad_commands=1, last_command_seq stays 2, pattern_set stays 1")
    if ctx.num("can_bad_commands") != 1:
        problems.append(f"summary can_bad_commands={ctx.summary.get('can_bad_commands')} (1 malformed sent)")
    return (FAIL, "; ".join(problems)) if problems else (PASS, "; ".join(details))


def check_gpio_outputs(ctx):
    r = need_run(ctx)
    if r:
        return r
    valid, beat = [], []
    for line in ctx.read("gpio_outputs.txt").splitlines():
        m = re.search(r"valid=(\d) heartbeat=(\d)", line)
        if m:
            valid.append(m.group(1))
            beat.append(m.group(2))
    beat_changes = sum(1 for a, b in zip(beat, beat[1:]) if a != b)
    valid_rises = sum(1 for a, b in zip(valid, valid[1:]) if a == "0" and b == "1")
    problems = []
    if beat_changes < 10:
        problems.append(f"heartbeat line changed only {beat_changes} times")
    if "1" not in valid:
        problems.append("pose-valid never high though sempose tracked")
    # re-acquisitions (select, re-acquire) drop pose-valid: it must have come back up
    if valid_rises < 2:
        problems.append(f"pose-valid rose {valid_rises} time(s); want >= 2 (start, and after a re-acquisition)")
    d = (f"heartbeat line: {beat_changes} changes seen by sampling sim_gpio2/value; pose-valid: "
         f"{valid_rises} rises, {len(valid)} samples")
    return (FAIL, "; ".join(problems) + " | " + d) if problems else (PASS, d)


def check_frame_sync(ctx):
    """sempose prints no frame-sync counters (GpioSyncedSource::counters() is not in the
    summary); a frame whose edge never came is completed as kBad and counted in scan_errors,
    and its pose says reason 'bad frame'. So: frames <= edges driven, few scan errors."""
    r = need_run(ctx)
    if r:
        return r
    m = re.match(r"(\d+)", ctx.read("sync_edges.txt"))
    if not m:
        return FAIL, "no sync_edges.txt"
    edges, frames, errors = int(m.group(1)), ctx.num("frames"), ctx.num("scan_errors")
    bad_poses = sum(1 for _, s in ctx.decoded.get(ID_ATTR, []) if int(s["reason"]) & REASON_BAD_FRAME)
    problems = []
    if frames > edges + 2:
        problems.append(f"frames={frames:g} > {edges} edges driven: frames completed without edges")
    if errors > max(2, 0.05 * frames):
        problems.append(f"scan_errors={errors:g} of {frames:g} frames (missed frame-sync edges)")
    d = (f"{edges} rising edges driven on line 0, {frames:g} frames, scan_errors={errors:g}, "
         f"{bad_poses} poses with reason 'bad frame'")
    return (FAIL, "; ".join(problems) + " | " + d) if problems else (PASS, d)


def _cyclictest(text):
    buckets = {}
    for line in text.splitlines():
        m = re.match(r"^(\d+)\s+(\d+)", line)
        if m:
            buckets[int(m.group(1))] = int(m.group(2))
    mx = re.search(r"# Max Latencies:\s*(\d+)", text)
    return buckets, (int(mx.group(1)) if mx else None)


def _pct(buckets, q):
    n = sum(buckets.values())
    acc = 0
    for us in sorted(buckets):
        acc += buckets[us]
        if acc >= q * n:
            return us
    return None


def check_histograms(ctx):
    """cyclictest's and sempose's histograms side by side (artifacts + p99/max printed).
    Latencies under TCG emulation are not meaningful; only their presence is checked."""
    cyc, cyc_max = _cyclictest(ctx.read("cyclictest_hist.txt"))
    if not cyc or cyc_max is None:
        return FAIL, "no or malformed cyclictest_hist.txt"
    try:
        with open(ctx.path("latency_hist.json")) as f:
            sem = json.load(f)
    except (OSError, ValueError) as e:
        return FAIL, f"sempose's latency_hist.json: {e}"
    if not os.path.isfile(ctx.path("latency_hist.txt")):
        return FAIL, "no latency_hist.txt from sempose (--hist-dir)"
    lines = [f"{'series':<22} {'n':>7} {'p99 us':>8} {'max us':>8}",
             f"{'cyclictest (idle)':<22} {sum(cyc.values()):>7} {_pct(cyc, 0.99):>8} {cyc_max:>8}"]
    series = sem.get("series", sem) if isinstance(sem, dict) else sem
    items = series.items() if isinstance(series, dict) else [(s.get("name"), s) for s in series]
    names = []
    for name, s in items:
        if not isinstance(s, dict):
            continue
        names.append(name)
        n = s.get("count", "?")
        p99 = s.get("p99_us", s.get("percentiles_us", {}).get("99", "?") if isinstance(s.get("percentiles_us"), dict) else "?")
        mx = s.get("max_us", (s.get("max_ns", 0) / 1e3) if "max_ns" in s else "?")
        fmt = lambda v: f"{v:.0f}" if isinstance(v, (int, float)) else str(v)
        lines.append(f"{'sempose ' + str(name):<22} {n:>7} {fmt(p99):>8} {fmt(mx):>8}")
    if "end_to_end" not in names:
        return FAIL, f"sempose's histograms lack end_to_end (has {names})"
    print("latency (TCG emulation: NOT meaningful, shown for the artifacts' sake):\n  " + "\n  ".join(lines))
    return PASS, f"cyclictest_hist.txt and latency_hist.{{txt,json}} side by side ({len(names)} sempose series)"


def check_comedi_end_to_end(ctx):
    """`sempose run` with source: comedi on the emulated SEM (sem_emul behind the real Comedi
    ioctls and mmap): rt_allocs=0, the poses on vcan (DBC-decoded) match the scene's known
    truth within what the simulator gives at the same dose (sim_reference.txt, measured on the
    host by `sempose replay` of simulated frames), and the arming cost is a histogram series."""
    if ctx.target.get("comedi_run", (SKIP, ""))[0] == SKIP:
        return SKIP, "no Comedi run (native box without comedi_test/sem_emul)"
    out = ctx.read("comedi/sempose_stdout.txt")
    summ = {}
    for line in reversed(out.splitlines()):
        if line.startswith("summary:"):
            summ = dict(re.findall(r"(\w+)=(\S+)", line))
            break
    if not summ:
        return FAIL, "no summary line in comedi/sempose_stdout.txt"
    bad = []
    if not re.search(r"^comedi: /dev/comedi\d+ \(sem_emul", out, re.M):
        bad.append("no 'comedi: /dev/comediN (sem_emul ...' setup line")
    if summ.get("rt_allocs") != "0":
        bad.append(f"rt_allocs={summ.get('rt_allocs')}")
    poses, frames = int(summ.get("poses", 0)), int(summ.get("frames", 0))
    if poses < 20:
        bad.append(f"only {poses} poses")
    if int(summ.get("scan_errors", 0)) > 0.05 * max(frames, 1):
        bad.append(f"scan_errors={summ.get('scan_errors')} of {frames} frames")
    truth = {}
    for row in csv.DictReader(io.StringIO(ctx.read("comedi/sem_scene_truth.csv"))):
        truth = {"x": float(row["x_px"]), "y": float(row["y_px"]), "phi": float(row["phi_deg"])}
        break
    ref = dict(re.findall(r"(\w+)=([-\d.]+)", ctx.read("comedi/sim_reference.txt")))
    if not truth or "rms_px" not in ref:
        return FAIL, "missing sem_scene_truth.csv or sim_reference.txt in the comedi artifacts"
    frames_log = ctx.load_log("comedi/candump.log") or []
    xy, attr = [], []
    for t, i, d in frames_log:
        name, sig = ctx.db.decode(i, d)
        if i == ID_XY:
            xy.append(sig)
        elif i == ID_ATTR:
            attr.append(sig)
    if len(xy) != int(summ.get("can_sent", -1)) or len(xy) != len(attr):
        bad.append(f"{len(xy)} XY / {len(attr)} ATTR frames on vcan vs can_sent={summ.get('can_sent')}")
    err_px, err_deg = [], []
    for sxy, sat in zip(xy, attr):
        if int(sat["state"]) != 0:   # TRACKING only
            continue
        dx, dy = sxy["x"] / NM_PER_PX_COMEDI - truth["x"], sxy["y"] / NM_PER_PX_COMEDI - truth["y"]
        err_px.append((dx * dx + dy * dy) ** 0.5)
        err_deg.append((sat["phi"] - truth["phi"] + 180) % 360 - 180)
    if len(err_px) < 0.8 * max(len(xy), 1):
        bad.append(f"only {len(err_px)} of {len(xy)} poses TRACKING")
    rms = lambda v: (sum(e * e for e in v) / len(v)) ** 0.5 if v else float("inf")
    rms_px, rms_deg = rms(err_px), rms(err_deg)
    sim_px, sim_deg = float(ref["rms_px"]), float(ref["rms_deg"])
    lim_px, lim_deg = max(1.5 * sim_px, sim_px + 0.25), max(1.5 * sim_deg, sim_deg + 0.5)
    if rms_px > lim_px or rms_deg > lim_deg:
        bad.append(f"RMS error {rms_px:.3f} px / {rms_deg:.3f} deg above {lim_px:.3f} px / {lim_deg:.3f} deg "
                   f"(simulator at the same dose: {sim_px:.3f} px / {sim_deg:.3f} deg)")
    arm = ""
    try:
        with open(ctx.path("comedi/latency_hist.json")) as f:
            sem = json.load(f)
        series = sem.get("series", sem) if isinstance(sem, dict) else sem
        items = dict(series.items()) if isinstance(series, dict) else {s.get("name"): s for s in series}
        a = items.get("arm")
        if not a or not a.get("count"):
            bad.append("no arm series in comedi/latency_hist.json")
        else:
            arm = f"; arming cost n={a.get('count')} p50={a.get('p50_us', '?')} us p99={a.get('p99_us', '?')} us"
    except (OSError, ValueError) as e:
        bad.append(f"comedi/latency_hist.json: {e}")
    d = (f"{poses} poses, {len(err_px)} TRACKING on vcan: RMS {rms_px:.3f} px / {rms_deg:.3f} deg vs truth "
         f"({truth['x']:.2f}, {truth['y']:.2f}, {truth['phi']:.2f}); simulator at the same dose {sim_px:.3f} px / "
         f"{sim_deg:.3f} deg; rt_allocs=0{arm}")
    return (FAIL, "; ".join(bad) + " | " + d) if bad else (PASS, d)


CHECKS = [check_target_side, check_summary, check_rt_setup, check_pose_frames, check_sequence,
          check_values_vs_csv, check_heartbeat, check_commands, check_gpio_outputs, check_frame_sync,
          check_histograms, check_comedi_end_to_end]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--artifacts", required=True)
    ap.add_argument("--dbc", default=os.path.join(SRC, "ipc", "sempose.dbc"))
    ap.add_argument("--duration", type=float, default=5)
    ap.add_argument("--report")
    a = ap.parse_args()
    ctx = Ctx(a.artifacts, a.dbc, a.duration)
    lines, failed = [], []
    for fn in CHECKS:
        name = fn.__name__[len("check_"):]
        try:
            st, detail = fn(ctx)
        except Exception as e:  # a checker bug is a failure, with the reason
            st, detail = FAIL, f"checker error: {type(e).__name__}: {e}"
        lines.append(f"{st:4} {name:16} {detail}")
        if st == FAIL:
            failed.append(name)
    lines.append(f"RESULT {'FAIL' if failed else 'PASS'}" + (f": {' '.join(failed)}" if failed else ""))
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    if a.report:
        with open(a.report, "w") as f:
            f.write(text)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
