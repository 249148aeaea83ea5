#!/usr/bin/python3
"""Issue 6's end-to-end check without a bus: run `sempose run --can-log FILE` on the
simulated SEM (virtual time), read the candump log with python-can's CanutilsLogReader,
decode every frame with ipc/sempose.dbc, and compare with the pipeline's own poses.csv:
every pose on the "bus", values equal, sequence counters without gaps, heartbeats present.

usage: check_can_log.py SEMPOSE CONFIG_TEMPLATE OUT_DIR
"""
import csv
import os
import subprocess
import sys

import can

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "ipc", "tools"))
from sempose_dbc import Dbc  # noqa: E402

STATES = {0: "TRACKING", 1: "ACQUIRING", 2: "LOST"}
SIM_NM_PER_PX = 40.0  # the scale of simulator-recorded patterns (firmware_host/pipeline tracker_setup.cpp)


def main(sempose, template, out):
    os.makedirs(out, exist_ok=True)
    cfg = os.path.join(out, "run.yaml")
    with open(template) as f, open(cfg, "w") as g:
        g.write(f.read().replace("@OUT@", out))
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
    for msg in can.CanutilsLogReader(log):
        name, sig = db.decode(msg.arbitration_id, msg.data)
        frames.setdefault(name, []).append(sig)
    with open(os.path.join(out, "poses.csv"), newline="") as f:
        rows = list(csv.DictReader(f))

    problems = []
    if int(fields["can_dropped"]) != 0 or int(fields["rt_allocs"]) != 0:
        problems.append(f"can_dropped={fields['can_dropped']} rt_allocs={fields['rt_allocs']}")
    if len(frames.get("HEARTBEAT", [])) < 2:
        problems.append(f"{len(frames.get('HEARTBEAT', []))} heartbeats")
    for target in (0, 1):
        mine = [r for r in rows if int(r["target"]) == target]
        xy, attr = frames.get(f"POSE_XY_T{target}", []), frames.get(f"POSE_ATTR_T{target}", [])
        if not mine or len(mine) != len(xy) or len(xy) != len(attr):
            problems.append(f"target {target}: {len(mine)} CSV rows, {len(xy)} XY, {len(attr)} ATTR frames")
            continue
        for k, (row, sxy, sat) in enumerate(zip(mine, xy, attr)):
            # x, y: nm at the pattern set's scale
            x_nm, y_nm = float(row["x_px"]) * SIM_NM_PER_PX, float(row["y_px"]) * SIM_NM_PER_PX
            if abs(sxy["x"] - round(x_nm)) > 1 or abs(sxy["y"] - round(y_nm)) > 1:
                problems.append(f"T{target} pose {k}: x,y {sxy['x']:g},{sxy['y']:g} vs {row['x_px']},{row['y_px']}")
            if abs(sat["phi"] - float(row["phi_deg"])) > 0.0011 or abs(sat["score"] - float(row["score"])) > 0.0011:
                problems.append(f"T{target} pose {k}: phi/score {sat['phi']:.3f}/{sat['score']:.3f} vs {row['phi_deg']}/{row['score']}")
            if STATES.get(int(sat["state"])) != row["status"]:
                problems.append(f"T{target} pose {k}: state {sat['state']:g} vs {row['status']}")
            if sxy["seq"] != sat["seq"] or sxy["seq"] != k % 256:
                problems.append(f"T{target} pose {k}: seq XY {sxy['seq']:g} ATTR {sat['seq']:g}, want {k % 256}")
        tracked = sum(r["status"] == "TRACKING" for r in mine) / len(mine)
        print(f"target {target}: {len(mine)} poses on the bus = CSV, seq without gaps, tracked {tracked:.1%}")
        if tracked < 0.9:
            problems.append(f"target {target}: tracked only {tracked:.1%}")
    return problems


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    found = main(*sys.argv[1:])
    for p in found[:20]:
        print("FAIL:", p)
    print(f"{0 if found else 1} passed, {1 if found else 0} failed")
    sys.exit(1 if found else 0)
