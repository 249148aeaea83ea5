#!/usr/bin/python3
"""Host-side checks of the sempose system test (run by run_system_test.sh).

check_results.py --artifacts DIR --dbc ipc/sempose.dbc --duration S [--report FILE]

Inputs (all in DIR, copied out of the VM): results.txt (guest CHECK lines), candump.log
(candump -L vcan0 during the sempose run), sempose_stdout.txt (last line: summary),
poses.csv (config output.poses_csv), sempose_can.log (--can-log), commands_sent.txt,
gpio_outputs.txt, cyclictest_hist.txt, system.yaml, sync_edges.txt.
Every check is a function returning (status, detail); status PASS / FAIL / SKIP. SKIP only
when the input artifact of an optional feature is absent; once sempose exists, its missing
outputs FAIL. Exit 0 when nothing failed.
"""
import argparse
import csv
import math
import os
import re
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dbc  # noqa: E402

PASS, FAIL, SKIP = "PASS", "FAIL", "SKIP"
INFRA = ["preempt_rt", "vcan", "gpio_sim", "can_selfcheck", "gpio_input", "gpio_output",
         "gpio_edge", "cyclictest"]


class Ctx:
    def __init__(self, art, dbc_path, duration):
        self.art = art
        self.duration = duration
        self.dbc_path = dbc_path
        self.db = dbc.Database.load(dbc_path) if dbc_path and os.path.isfile(dbc_path) else None
        self.guest = {}
        for line in self.read("results.txt").splitlines():
            m = re.match(r"CHECK (\S+) (PASS|FAIL|SKIP) ?(.*)", line)
            if m:
                self.guest[m.group(1)] = (m.group(2), m.group(3))
        self.sempose_ran = "sempose_exit" in self.guest
        self.summary = {}
        for line in reversed(self.read("sempose_stdout.txt").splitlines()):
            if line.startswith("summary:"):
                for k, v in re.findall(r"(\w+)=(\S+)", line):
                    self.summary[k] = v
                break
        self.frames = self.load_log("candump.log")
        self.canlog = self.load_log("sempose_can.log")
        self.config = self.read("system.yaml")

    def path(self, name):
        return os.path.join(self.art, name)

    def has(self, name):
        return os.path.isfile(self.path(name))

    def read(self, name):
        try:
            with open(self.path(name), encoding="utf-8", errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def load_log(self, name):
        """[(t, id, bytes)] from a candump -L / -l log, read with python-can."""
        if not self.has(name):
            return None
        import can
        out = []
        try:
            for msg in can.CanutilsLogReader(self.path(name)):
                if msg.is_error_frame or msg.is_remote_frame:
                    continue
                out.append((msg.timestamp, msg.arbitration_id, bytes(msg.data)))
        except Exception as e:  # a torn last line when the VM stopped: keep what was read
            print(f"warning: {name}: {e}", file=sys.stderr)
        return out

    def cfg(self, key, default=None):
        m = re.search(rf"^\s*{key}\s*:\s*([^#\n]+)", self.config, re.M)
        return m.group(1).strip() if m else default

    def sem_float(self, key):
        try:
            return float(self.summary[key])
        except (KeyError, ValueError):
            return None

    # DBC roles, found by name so the checker follows ipc/sempose.dbc.
    def pose_msgs(self, target0=False):
        """Pose messages that actually appear on vcan0 (classic XY+ATTR or the FD one);
        with target0, only those of the first target block (name ends in T0 / _0)."""
        if not self.db:
            return []
        ids = {i for _, i, _ in (self.frames or [])}
        msgs = [m for m in self.db.find(r"pose") if m.frame_id in ids]
        if target0:
            t0 = [m for m in msgs if re.search(r"(T0|_0)$", m.name, re.I)]
            msgs = t0 or msgs[:2]
        return msgs

    def heartbeat_msg(self):
        if not self.db:
            return None
        m = self.db.find(r"heartbeat|status", exclude=r"pose|cmd|command")
        return m[0] if m else None

    def command_msg(self):
        m = self.db.find(r"command|cmd") if self.db else []
        return m[0] if m else None

    def frames_of(self, msg, frames=None):
        frames = self.frames if frames is None else frames
        return [(t, d) for t, i, d in (frames or []) if i == msg.frame_id]


def need_sempose(ctx):
    """None when the sempose-dependent checks can run, else (FAIL, why)."""
    if not ctx.sempose_ran:
        st = ctx.guest.get("sempose_present") or ctx.guest.get("sempose_built")
        return FAIL, f"sempose did not run in the VM ({st[1] if st else 'no record'})"
    if "sempose_built" in ctx.guest:
        return FAIL, ctx.guest["sempose_built"][1]
    return None


def need_dbc(ctx):
    if ctx.db is None:
        return FAIL, f"no DBC at {ctx.dbc_path}"
    return None


# ----------------------------------------------------------------------------------------
def check_guest_infra(ctx):
    bad = [f"{n}: {ctx.guest[n][1]}" for n in INFRA if ctx.guest.get(n, (FAIL,))[0] != PASS]
    missing = [n for n in INFRA if n not in ctx.guest]
    if bad:
        return FAIL, "; ".join(bad) + (f" (missing: {missing})" if missing else "")
    return PASS, "PREEMPT_RT, vcan0, gpio-sim, candump loop, gpio in/out/edge, cyclictest"


def check_sempose_run(ctx):
    r = need_sempose(ctx)
    if r:
        return r
    st, detail = ctx.guest["sempose_exit"]
    if st != PASS:
        return FAIL, detail
    if not ctx.summary:
        return FAIL, "no 'summary:' line on sempose's stdout"
    want = ["poses", "poses_per_s", "tracked_share", "dropped", "overruns", "rt_allocs",
            "e2e_us_p50", "e2e_us_p99", "e2e_us_p999", "e2e_us_max", "dwell_ns_min", "dwell_ns_max"]
    missing = [k for k in want if k not in ctx.summary]
    if missing:
        return FAIL, f"summary lacks {missing}"
    if ctx.sem_float("poses") <= 0:
        return FAIL, "summary says poses=0"
    return PASS, " ".join(f"{k}={ctx.summary[k]}" for k in want[:6])


def check_guest_bindings(ctx):
    r = need_sempose(ctx)
    if r:
        return r
    bad = [f"{n}: {ctx.guest[n][1]}" for n in ("sempose_can_bound", "sempose_gpio_requested")
           if ctx.guest.get(n, (FAIL, "not recorded"))[0] != PASS]
    return (FAIL, "; ".join(bad)) if bad else (PASS, "CAN socket bound on vcan0, frame-sync line requested")


def check_pose_rate(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    if ctx.frames is None:
        return FAIL, "no candump.log"
    msgs = ctx.pose_msgs()
    if not msgs:
        return FAIL, (f"no pose frames on vcan0 (DBC pose ids: "
                      f"{[hex(m.frame_id) for m in ctx.db.find(r'pose')][:8]})")
    poses = ctx.sem_float("poses")
    rate = ctx.sem_float("poses_per_s")
    details, ok = [], True
    for m in msgs:
        fr = ctx.frames_of(m)
        if not fr:
            ok = False
            details.append(f"{m.name}: no frames on vcan0")
            continue
        span = fr[-1][0] - fr[0][0]
        r_obs = (len(fr) - 1) / span if span > 0 else 0.0
        d = f"{m.name}: {len(fr)} frames, {r_obs:.1f}/s"
        if poses is not None and abs(len(fr) - poses) > max(2, 0.02 * poses):
            ok = False
            d += f" but summary poses={poses:.0f}"
        if rate and r_obs and not 0.5 * rate <= r_obs <= 1.5 * rate:
            ok = False
            d += f" but summary poses_per_s={rate}"
        details.append(d)
    edges = re.match(r"(\d+)", ctx.read("sync_edges.txt"))
    if edges:
        details.append(f"{edges.group(1)} frame-sync edges driven")
    return (PASS if ok else FAIL), "; ".join(details)


def _counter(msg):
    return msg.find_signal(r"seq|counter")


def check_sequence(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    if ctx.frames is None:
        return FAIL, "no candump.log"
    allowed = int(ctx.sem_float("dropped") or 0)
    for k, v in ctx.summary.items():   # send-side drops (EAGAIN/ENOBUFS) are counted drops too
        if re.search(r"can.*(drop|eagain|enobufs)", k):
            try:
                allowed += int(float(v))
            except ValueError:
                pass
    details, ok = [], True
    seqs = {}
    if not ctx.pose_msgs():
        return FAIL, "no pose frames on vcan0"
    for m in ctx.pose_msgs():
        sig = _counter(m)
        fr = ctx.frames_of(m)
        if sig is None:
            ok = False
            details.append(f"{m.name}: no counter signal (seq|counter)")
            continue
        if not fr:
            ok = False
            details.append(f"{m.name}: no frames")
            continue
        vals = [sig.raw(d) for _, d in fr]
        seqs[m.name] = vals
        mod = 1 << sig.length
        gaps = [(a, b) for a, b in zip(vals, vals[1:]) if (b - a) % mod != 1]
        missing = sum(((b - a) % mod) - 1 for a, b in gaps)
        d = f"{m.name}.{sig.name}: {len(vals)} values, {len(gaps)} gaps ({missing} missing)"
        if gaps and missing > allowed:
            ok = False
            d += f" > counted drops {allowed}; first gaps {gaps[:5]}"
        details.append(d)
    if len(seqs) >= 2:   # the frames of one pose share the counter
        names = list(seqs)
        a, b = set(seqs[names[0]]), set(seqs[names[1]])
        if a != b and len(a ^ b) > 2:
            ok = False
            details.append(f"{names[0]}/{names[1]} counters differ in {len(a ^ b)} values")
    return (PASS if ok else FAIL), "; ".join(details)


def _csv_rows(ctx):
    path = ctx.cfg("poses_csv", "/out/poses.csv")
    name = os.path.basename(path)
    if not ctx.has(name):
        return None, name
    with open(ctx.path(name), newline="") as f:
        return list(csv.DictReader(f)), name


def check_values_vs_csv(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    rows, name = _csv_rows(ctx)
    if rows is None:
        return FAIL, f"no pose CSV ({name}; config output.poses_csv)"
    if not rows:
        return FAIL, f"{name} has no rows"
    for col in ("x_px", "y_px", "phi_deg", "score", "status"):
        if col not in rows[0]:
            return FAIL, f"{name} lacks column {col} (has {list(rows[0])})"
    # decode every pose frame; pair pose messages by counter
    if "target" in rows[0]:
        rows = [r for r in rows if r["target"] in ("0", "")]
    decoded = {}
    for m in ctx.pose_msgs(target0=True):
        sig = _counter(m)
        for i, (t, d) in enumerate(ctx.frames_of(m)):
            key = sig.raw(d) if sig else i
            decoded.setdefault(m.name, []).append((key, m.decode(d)))
    if not decoded:
        return FAIL, "no pose frames to compare"
    # merge the frames of a pose: walk in order, one record per counter value
    merged = []
    names = list(decoded)
    first = decoded[names[0]]
    others = {n: {} for n in names[1:]}
    for n in names[1:]:
        for k, v in decoded[n]:
            others[n].setdefault(k, []).append(v)
    for k, v in first:
        rec = dict(v)
        for n in names[1:]:
            lst = others[n].get(k)
            if lst:
                rec.update(lst.pop(0))
        merged.append(rec)

    def sig_for(pattern):
        for m in ctx.pose_msgs(target0=True):
            s = m.find_signal(pattern)
            if s:
                return s
        return None
    sx, sy = sig_for(r"^x|_x\b|x_"), sig_for(r"^y|_y\b|y_")
    sphi, sscore, sstat = sig_for(r"phi|angle|theta"), sig_for(r"score"), sig_for(r"status|state")
    if not (sx and sy):
        return FAIL, "pose messages lack x/y signals"

    def csv_f(row, c):
        try:
            return float(row[c])
        except (ValueError, TypeError):
            return math.nan
    # align CSV rows and frames in order; allow a small offset (poses written but not sent)
    n = min(len(rows), len(merged))
    best = None
    for off in range(-5, 6):
        pairs = [(rows[i + off], merged[i]) for i in range(len(merged)) if 0 <= i + off < len(rows)]
        if len(pairs) < max(1, n - 5):
            continue
        xs = [(csv_f(a, "x_px"), b.get(sx.name)) for a, b in pairs]
        num = sum(p * f for p, f in xs if not math.isnan(p))
        den = sum(p * p for p, f in xs if not math.isnan(p))
        k = num / den if den else 1.0   # nm per px, fitted (the frames carry nm)
        err = sum(abs(f - k * p) for p, f in xs if not math.isnan(p))
        if best is None or err < best[0]:
            best = (err, off, pairs, k)
    if best is None:
        return FAIL, f"cannot align {len(rows)} CSV rows with {len(merged)} pose records"
    _, off, pairs, k = best
    cfg_k = ctx.cfg("nm_per_px")
    bad = []
    tol_xy = max(sx.factor, sy.factor) + 1e-6
    # nm/px may change when a select-pattern command carries a new scale: allow one
    # re-fit per select command sent, everything else must match the current scale.
    selects = sum(1 for lbl, _ in _sent_commands(ctx) if lbl.startswith("select"))
    scale, segments = k, 1
    for a, b in pairs:
        px, py = csv_f(a, "x_px"), csv_f(a, "y_px")
        fx, fy = b.get(sx.name, math.nan), b.get(sy.name, math.nan)

        def fits(sc):
            return all(math.isnan(p) or abs(f - sc * p) <= tol_xy + abs(sc) * 0.01
                       for p, f in ((px, fx), (py, fy)))
        if not fits(scale):
            ref = (px, fx) if abs(px) >= abs(py) else (py, fy)
            new = ref[1] / ref[0] if ref[0] else math.nan
            if segments <= selects and not math.isnan(new) and fits(new):
                scale, segments = new, segments + 1
            else:
                bad.append(f"row {a.get('frame')}: {sx.name},{sy.name}=({fx},{fy}) vs "
                           f"px ({px},{py}) at {scale:.4g} nm/px")
        if sphi is not None and sphi.name in b:
            p = csv_f(a, "phi_deg")
            sc = 1000.0 if "m" in sphi.unit.lower() else 1.0
            if not math.isnan(p) and abs(b[sphi.name] - sc * p) > sphi.factor + 0.002 * sc:
                bad.append(f"row {a.get('frame')}: {sphi.name}={b[sphi.name]} vs phi_deg={p}")
        if sscore is not None and sscore.name in b:
            p = csv_f(a, "score")
            if not math.isnan(p) and abs(b[sscore.name] - p) > sscore.factor + 1e-3:
                bad.append(f"row {a.get('frame')}: {sscore.name}={b[sscore.name]} vs score={p}")
        if sstat is not None and sstat.choices and sstat.name in b:
            name = sstat.choices.get(int(b[sstat.name]), str(b[sstat.name]))
            if a["status"] and not (a["status"].strip().upper() in name.upper()
                                    or a["status"].strip() == str(int(b[sstat.name]))):
                bad.append(f"row {a.get('frame')}: {sstat.name}={name} vs status={a['status']}")
    detail = (f"{len(pairs)} poses compared (CSV offset {off}, fitted {k:.4g} nm/px, "
              f"{segments} scale segment(s)"
              f"{', config ' + cfg_k if cfg_k else ''})")
    if k <= 0:
        bad.insert(0, f"fitted nm/px {k} <= 0")
    if bad:
        return FAIL, f"{detail}; {len(bad)} mismatches, first: {bad[:4]}"
    return PASS, detail


def check_heartbeat(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    hb = ctx.heartbeat_msg()
    if hb is None:
        return FAIL, "no heartbeat/status message in the DBC"
    fr = ctx.frames_of(hb) if ctx.frames is not None else []
    hz = float(ctx.cfg("heartbeat_hz", "0") or 0)
    if not fr:
        return FAIL, f"no {hb.name} frames on vcan0"
    d = f"{len(fr)} {hb.name} frames"
    if hz > 0:
        span = fr[-1][0] - fr[0][0]
        obs = (len(fr) - 1) / span if span > 0 else 0
        d += f" at {obs:.1f}/s (config {hz:g} Hz)"
        if not 0.5 * hz <= obs <= 1.5 * hz:
            return FAIL, d
    return PASS, d


def _sent_commands(ctx):
    out = []
    for line in ctx.read("commands_sent.txt").splitlines():
        p = line.split()
        if len(p) >= 3 and "SEND-FAILED" not in line:
            out.append((p[1], p[2]))
    return out


def check_bad_commands(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    sent = _sent_commands(ctx)
    bad_sent = [lbl for lbl, _ in sent if lbl.startswith("bad_")]
    if not sent:
        return FAIL, "no command frames were injected (see commands_planned.txt / make_commands.log)"
    counted = []
    for k, v in ctx.summary.items():
        if re.search(r"bad|invalid|reject", k):
            counted.append((f"summary {k}", float(v)))
    hb = ctx.heartbeat_msg()
    if hb:
        s = hb.find_signal(r"bad|invalid|reject")
        if s:
            vals = [s.decode(d) for _, d in ctx.frames_of(hb)]
            if vals:
                counted.append((f"{hb.name}.{s.name} (last)", vals[-1]))
    if not counted:
        return FAIL, "no bad-command counter in the summary nor in the heartbeat"
    wrong = [(n, v) for n, v in counted if v != len(bad_sent)]
    d = f"{len(bad_sent)} bad frames sent ({', '.join(bad_sent)}); " + \
        ", ".join(f"{n}={v:g}" for n, v in counted)
    return (FAIL if wrong else PASS), d


def check_command_effects(ctx):
    r = need_sempose(ctx) or need_dbc(ctx)
    if r:
        return r
    sent = dict(_sent_commands(ctx))
    cmd = ctx.command_msg()
    if cmd is None or ctx.frames is None:
        return FAIL, "no command message in the DBC or no candump.log"
    # the injected frames are in candump.log too: use their timestamps
    times = {}
    for t, i, d in ctx.frames:
        if i == cmd.frame_id:
            for lbl, f in sent.items():
                if f.split("#", 1)[1].upper() == d.hex().upper() and lbl not in times:
                    times[lbl] = t
    details, ok = [], True
    hb = ctx.heartbeat_msg()
    if "select_pattern_set_1" in times and hb is not None:
        s = hb.find_signal(r"pattern")
        if s is None:
            details.append(f"{hb.name} has no pattern signal: select not checked")
        else:
            after = [s.decode(d) for t, d in ctx.frames_of(hb) if t > times["select_pattern_set_1"]]
            if 1 in after:
                details.append(f"select pattern set 1 -> {hb.name}.{s.name}=1")
            else:
                ok = False
                details.append(f"select pattern set 1 not reflected in {hb.name}.{s.name} ({sorted(set(after))})")
    elif "select_pattern_set_1" not in sent:
        details.append("no select command planned")
    else:
        ok = False
        details.append("select command not seen on vcan0")
    if "reacquire" in times:
        st = None
        for m in ctx.pose_msgs():
            st = m.find_signal(r"status|state")
            if st:
                break
        acq = st.choice_value(r"acquir") if st is not None else None
        if acq is None:
            details.append("no ACQUIRING status value in the DBC: re-acquire not checked")
        else:
            after = [st.raw(d) for t, d in ctx.frames_of(m) if t > times["reacquire"]][:200]
            if acq in after:
                details.append(f"re-acquire -> {st.name}={st.choices[acq]} in a following frame")
            else:
                ok = False
                details.append(f"re-acquire: no {st.choices[acq]} status in the following frames")
    return (PASS if ok else FAIL), "; ".join(details)


def check_gpio_outputs(ctx):
    r = need_sempose(ctx)
    if r:
        return r
    if not ctx.has("gpio_outputs.txt"):
        return FAIL, "no gpio_outputs.txt"
    valid, beat = [], []
    for line in ctx.read("gpio_outputs.txt").splitlines():
        m = re.search(r"valid=(\d) heartbeat=(\d)", line)
        if m:
            valid.append(m.group(1))
            beat.append(m.group(2))
    beat_changes = sum(1 for a, b in zip(beat, beat[1:]) if a != b)
    d = f"heartbeat line: {beat_changes} changes seen; pose-valid: {''.join(dict.fromkeys(valid)) or '-'}"
    ok = beat_changes >= 2
    tracked = ctx.sem_float("tracked_share")
    if tracked and tracked > 0 and "1" not in valid:
        ok = False
        d += " (never high though tracked_share>0)"
    return (PASS if ok else FAIL), d


def check_can_log(ctx):
    r = need_sempose(ctx)
    if r:
        return r
    if ctx.canlog is None:
        return SKIP, "no sempose_can.log (run without --can-log)"
    if not ctx.canlog:
        return FAIL, "sempose_can.log is empty"
    ids = {i for _, i, _ in ctx.canlog}
    live = [(i, d) for _, i, d in (ctx.frames or []) if i in ids]
    if not live:
        return FAIL, (f"{len(ctx.canlog)} frames in --can-log but none of those ids on vcan0: "
                      "--can-log seems to replace the SocketCAN sink")
    # compare per id (the log and the socket may be written from different threads)
    logged = [(i, d) for _, i, d in ctx.canlog]
    diff = 0
    for fid in ids:
        a = [d for i, d in logged if i == fid]
        b = [d for i, d in live if i == fid]
        diff += sum(1 for x, y in zip(a, b) if x != y) + abs(len(a) - len(b))
    if diff > 2:
        return FAIL, f"--can-log ({len(logged)}) and vcan0 ({len(live)}) differ in {diff} frames"
    return PASS, f"{len(logged)} frames, same as on vcan0"


def check_histograms(ctx):
    hist = ctx.read("cyclictest_hist.txt")
    if not hist:
        return FAIL, "no cyclictest_hist.txt"
    rows = [l for l in hist.splitlines() if re.match(r"^\d+\s+\d+", l)]
    mx = re.search(r"# Max Latencies:\s*(\d+)", hist)
    if not rows or not mx:
        return FAIL, "cyclictest histogram malformed"
    d = f"cyclictest: {len(rows)} buckets, max {int(mx.group(1))} us"
    if ctx.sempose_ran and "sempose_built" not in ctx.guest:
        known = {"cyclictest_hist.txt", "cyclictest_stderr.txt", "candump.log", "candump_stderr.txt",
                 "sempose_stdout.txt", "sempose_stderr.txt", "sempose_can.log", "system.yaml",
                 "gpio_outputs.txt", "gpio_chip.txt", "sync_edges.txt", "commands_sent.txt",
                 "dmesg.txt", "interrupts.txt", "lsmod.txt", "sempose_exit_code.txt",
                 "results.txt", "console.log", "commands_planned.txt"}
        _, csvname = _csv_rows(ctx)
        sem = sorted(f for f in os.listdir(ctx.art) if f not in known and f != csvname
                     and os.path.isfile(ctx.path(f)))
        if not sem:
            return FAIL, d + "; sempose wrote no histogram into --hist-dir"
        d += f"; sempose: {', '.join(sem)}"
    return PASS, d


CHECKS = [check_guest_infra, check_sempose_run, check_guest_bindings, check_pose_rate,
          check_sequence, check_values_vs_csv, check_heartbeat, check_bad_commands,
          check_command_effects, check_gpio_outputs, check_can_log, check_histograms]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--artifacts", required=True)
    ap.add_argument("--dbc", default="")
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
        lines.append(f"{st:4} {name:20} {detail}")
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
