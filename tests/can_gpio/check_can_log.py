#!/usr/bin/python3
"""Issue 6's end-to-end check without a bus: run `sempose run --can-log FILE` on the
simulated SEM (virtual time), read the candump log with python-can's CanutilsLogReader,
decode every frame with ipc/sempose.dbc, and compare with the pipeline's own poses.csv:
every pose on the "bus", values equal (σ and scale in POSE_UNC too), sequence counters without
gaps, heartbeats present, σ measured on the tracked poses, and every pose's angle order (the
procedural lamella's two-fold symmetry: 2; the gripper: 1) on the bus as in the CSV.

With --fd the same run with `can.fd: on`: every pose one 64-byte POSE_FD frame (FD-flagged in
the log, no classic pose frames), its full-resolution values (32-bit seq, nm, mdeg, σ in µdeg)
equal to the CSV's, the target and pattern set in the frame, and the heartbeats' fd bit set.

usage: check_can_log.py SEMPOSE CONFIG_TEMPLATE OUT_DIR [--fd]
"""
import csv
import os
import subprocess
import sys

import can

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "ipc", "tools"))
from sempose_dbc import Dbc  # noqa: E402

STATES = {0: "TRACKING", 1: "ACQUIRING", 2: "LOST", 3: "UNCERTAIN"}
# The rotational order each target's pattern declares (pose README, Symmetric targets).
ANGLE_ORDER = {0: 2, 1: 1}
SIM_NM_PER_PX = 40.0  # the scale of simulator-recorded patterns (firmware_host/pipeline tracker_setup.cpp)


def main(sempose, template, out, fd=False):
    os.makedirs(out, exist_ok=True)
    cfg = os.path.join(out, "run.yaml")
    with open(template) as f, open(cfg, "w") as g:
        text = f.read().replace("@OUT@", out)
        if fd:
            if "can: {heartbeat_hz: 20}" not in text:
                return [f"{template}: no `can: {{heartbeat_hz: 20}}` line to turn CAN FD on in"]
            text = text.replace("can: {heartbeat_hz: 20}", 'can: {heartbeat_hz: 20, fd: "on"}')
        g.write(text)
    log = os.path.join(out, "can.log")
    run = subprocess.run([sempose, "run", "--config", cfg, "--duration", "2", "--can-log", log],
                         capture_output=True, text=True, timeout=120)
    summary = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else ""
    if run.returncode != 0 or not summary.startswith("summary:"):
        return [f"sempose run failed (rc {run.returncode}): {run.stderr[-2000:]}"]
    fields = dict(kv.split("=", 1) for kv in summary.split()[1:])
    print(summary)

    db = Dbc.load(os.path.join(REPO, "ipc", "sempose.dbc"))
    frames = {}  # message name -> [signals]
    problems = []
    for msg in can.CanutilsLogReader(log):
        name, sig = db.decode(msg.arbitration_id, msg.data)
        frames.setdefault(name, []).append(sig)
        # The DBC's frame format: POSE_FD only as an FD frame of 64 bytes, the rest classic.
        want_fd = name is not None and name.startswith("POSE_FD")
        if msg.is_fd != want_fd or (want_fd and len(msg.data) != 64):
            problems.append(f"{name or hex(msg.arbitration_id)}: is_fd={msg.is_fd} len={len(msg.data)}")
    with open(os.path.join(out, "poses.csv"), newline="") as f:
        rows = list(csv.DictReader(f))

    if int(fields["can_dropped"]) != 0 or int(fields["rt_allocs"]) != 0:
        problems.append(f"can_dropped={fields['can_dropped']} rt_allocs={fields['rt_allocs']}")
    if len(frames.get("HEARTBEAT", [])) < 2:
        problems.append(f"{len(frames.get('HEARTBEAT', []))} heartbeats")
    if any(int(h["fd"]) != int(fd) for h in frames.get("HEARTBEAT", [])):
        problems.append(f"a heartbeat's fd bit is not {int(fd)}")
    if fd:
        return problems + check_fd(frames, rows)
    for target in (0, 1):
        mine = [r for r in rows if int(r["target"]) == target]
        xy, attr = frames.get(f"POSE_XY_T{target}", []), frames.get(f"POSE_ATTR_T{target}", [])
        unc = frames.get(f"POSE_UNC_T{target}", [])
        if not mine or len(mine) != len(xy) or len(xy) != len(attr) or len(xy) != len(unc):
            problems.append(f"target {target}: {len(mine)} CSV rows, {len(xy)} XY, {len(attr)} ATTR, {len(unc)} UNC frames")
            continue
        with_sigma = 0
        for k, (row, sxy, sat, su) in enumerate(zip(mine, xy, attr, unc)):
            # σ in nm at the pattern set's scale (0.1 nm steps), σφ in mdeg, the target's scale
            for axis in ("x", "y"):
                want = min(409.5, float(row[f"sigma_{axis}_px"]) * SIM_NM_PER_PX)
                if abs(su[f"sigma_{axis}"] - want) > 0.051:
                    problems.append(f"T{target} pose {k}: sigma_{axis} {su[f'sigma_{axis}']:g} nm vs {row[f'sigma_{axis}_px']} px")
            if abs(su["sigma_phi"] - min(2.047, float(row["sigma_phi_deg"]))) > 0.0006:
                problems.append(f"T{target} pose {k}: sigma_phi {su['sigma_phi']:g} vs {row['sigma_phi_deg']}")
            if abs(su["sigma_scale"] - min(0.0635, float(row["sigma_scale"]))) > 0.00026:
                problems.append(f"T{target} pose {k}: sigma_scale {su['sigma_scale']:g} vs {row['sigma_scale']}")
            if abs(su["target_scale"] - float(row["scale"])) > 0.00011:
                problems.append(f"T{target} pose {k}: scale {su['target_scale']:g} vs {row['scale']}")
            if su["seq"] != k % 256:
                problems.append(f"T{target} pose {k}: UNC seq {su['seq']:g}, want {k % 256}")
            with_sigma += row["status"] == "TRACKING" and float(row["sigma_x_px"]) > 0 and float(row["sigma_phi_deg"]) > 0
            # x, y: nm at the pattern set's scale
            x_nm, y_nm = float(row["x_px"]) * SIM_NM_PER_PX, float(row["y_px"]) * SIM_NM_PER_PX
            if abs(sxy["x"] - round(x_nm)) > 1 or abs(sxy["y"] - round(y_nm)) > 1:
                problems.append(f"T{target} pose {k}: x,y {sxy['x']:g},{sxy['y']:g} vs {row['x_px']},{row['y_px']}")
            if abs(sat["phi"] - float(row["phi_deg"])) > 0.0011 or abs(sat["score"] - float(row["score"])) > 0.0011:
                problems.append(f"T{target} pose {k}: phi/score {sat['phi']:.3f}/{sat['score']:.3f} vs {row['phi_deg']}/{row['score']}")
            if int(sat["angle_order"]) != int(row["angle_order"]) or int(row["angle_order"]) != ANGLE_ORDER[target]:
                problems.append(f"T{target} pose {k}: angle_order {sat['angle_order']:g} on the bus, {row['angle_order']} in the CSV, "
                                f"want {ANGLE_ORDER[target]}")
            if STATES.get(int(sat["state"])) != row["status"]:
                problems.append(f"T{target} pose {k}: state {sat['state']:g} vs {row['status']}")
            if sxy["seq"] != sat["seq"] or sxy["seq"] != k % 256:
                problems.append(f"T{target} pose {k}: seq XY {sxy['seq']:g} ATTR {sat['seq']:g}, want {k % 256}")
        n_tracked = sum(r["status"] == "TRACKING" for r in mine)
        tracked = n_tracked / len(mine)
        print(f"target {target}: {len(mine)} poses on the bus = CSV, seq without gaps, tracked {tracked:.1%}, "
              f"sigma on {with_sigma} of {n_tracked} tracked poses, angle order {ANGLE_ORDER[target]}")
        # Every tracked pose but a start search's has its σ (the first pose, and one after a loss).
        if with_sigma < 0.9 * n_tracked:
            problems.append(f"target {target}: sigma on only {with_sigma} of {n_tracked} tracked poses")
        if tracked < 0.9:
            problems.append(f"target {target}: tracked only {tracked:.1%}")
    return problems


def check_fd(frames, rows):
    """Every pose one POSE_FD frame equal to its CSV row (the CSV's printed digits bound the
    tolerances; the frame's own steps are finer)."""
    problems = []
    if any(n.startswith(("POSE_XY", "POSE_ATTR", "POSE_UNC")) for n in frames):
        problems.append("classic pose frames sent in FD mode: " + ", ".join(sorted(frames)))
    for target in (0, 1):
        mine = [r for r in rows if int(r["target"]) == target]
        fdf = frames.get(f"POSE_FD_T{target}", [])
        if not mine or len(mine) != len(fdf):
            problems.append(f"target {target}: {len(mine)} CSV rows, {len(fdf)} POSE_FD frames")
            continue
        for k, (row, f) in enumerate(zip(mine, fdf)):
            want = {
                "x": (float(row["x_px"]) * SIM_NM_PER_PX, 1.0),
                "y": (float(row["y_px"]) * SIM_NM_PER_PX, 1.0),
                "phi": (float(row["phi_deg"]), 0.0011),
                "score": (float(row["score"]), 0.0011),
                "target_scale": (float(row["scale"]), 0.00011),
                "sigma_x": (float(row["sigma_x_px"]) * SIM_NM_PER_PX, 0.051),
                "sigma_y": (float(row["sigma_y_px"]) * SIM_NM_PER_PX, 0.051),
                "sigma_phi": (float(row["sigma_phi_deg"]), 0.0006),
                "sigma_scale": (float(row["sigma_scale"]), 0.00026),
                "scale": (SIM_NM_PER_PX, 0.0011),
                "seq": (k, 0),
                "target": (target, 0),
                "angle_order": (ANGLE_ORDER[target], 0),
            }
            for sig, (value, tol) in want.items():
                if abs(f[sig] - value) > tol:
                    problems.append(f"T{target} pose {k}: {sig} {f[sig]:g} on the bus, {value:g} from the CSV")
            if int(row["angle_order"]) != ANGLE_ORDER[target]:
                problems.append(f"T{target} pose {k}: angle_order {row['angle_order']} in the CSV, want {ANGLE_ORDER[target]}")
            if STATES.get(int(f["state"])) != row["status"]:
                problems.append(f"T{target} pose {k}: state {f['state']:g} vs {row['status']}")
        tracked = sum(r["status"] == "TRACKING" for r in mine) / len(mine)
        print(f"target {target}: {len(mine)} poses as POSE_FD frames = CSV, 32-bit seq without gaps, tracked {tracked:.1%}")
        if tracked < 0.9:
            problems.append(f"target {target}: tracked only {tracked:.1%}")
    return problems


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--fd"]
    if len(args) != 3:
        sys.exit(__doc__)
    found = main(*args, fd="--fd" in sys.argv[1:])
    for p in found[:20]:
        print("FAIL:", p)
    print(f"{0 if found else 1} passed, {1 if found else 0} failed")
    sys.exit(1 if found else 0)
