#!/usr/bin/python3
"""Held-out end-to-end check: scenes made from two real SEM micrographs no tuning has seen
(needle_lamella_post_eb.pgm, holey_grid_eb.pgm), run through the path an outside tester uses:

  sempose sim --out REC (full-field PGMs, frames.csv, ground_truth.csv)
  sempose pattern       (the pattern from a still recording, as an operator makes it)
  sempose replay --truth (the poses CSV)

and every pose compared with the ground truth. Per sequence it prints the TRACKING share, the
false TRACKING poses (> 3 px or > 10 deg off; per target), the RMS error over TRACKING poses and
the time the three commands took. Exit 1 when a rule is broken:
  - any false TRACKING pose at >= 2.5 e-/px;
  - more than 1 % of the poses false TRACKING over the 1 e-/px sequences (pooled);
  - a sequence marked easy TRACKING less than its stated share (a tracker that reports nothing
    never lies, so silence must fail too);
  - a command that crashed, hung (timeout) or failed.
Python 3 standard library only; nothing outside the repository and the build is read.
"""
import argparse
import csv
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

FIELD_W, FIELD_H = 640, 480
DWELL_NS = 250          # the moving recording's dwell
PATTERN_DWELL_NS = 2000  # the operator records the pattern with a slow scan (8x the dose)
YIELD = 0.1
FALSE_PX, FALSE_DEG = 3.0, 10.0


def beam_pa(dose):
    """Beam current for `dose` detected electrons per pixel at brightness 1 (README: detector)."""
    return dose / (6.24 * DWELL_NS * 1e-3 * YIELD)


# --- scene pieces ------------------------------------------------------------------------
# The needle carrying its lamella (needle_lamella_post_eb.pgm, left edge): the needle's last
# ~150 px, the gap, the lamella; both regions kept by the threshold mask, shown at half size.
def needle_lamella(data, x, y, phi=0.0, trajectory="static", extra="", brightness=1.3):
    return (f"    - texture: {{path: {data}/needle_lamella_post_eb.pgm, crop: [40, 380, 360, 190], "
            f"mask: threshold_all, mask_level: 0.3}}\n"
            f"      size: [180, 95]\n"
            f"      brightness: {brightness}\n"
            f"      start: [{x}, {y}, {phi}]\n"
            f"      trajectory: {{{trajectory}}}\n{extra}")


# A patch of the hole lattice (holey_grid_eb.pgm), the whole square: over the lattice itself its
# look-alikes lie one period (~43 px) away in every direction.
def lattice_patch(data, x, y, phi=0.0, trajectory="static", extra=""):
    return (f"    - texture: {{path: {data}/holey_grid_eb.pgm, crop: [560, 330, 150, 150], mask: full}}\n"
            f"      size: [150, 150]\n"
            f"      start: [{x}, {y}, {phi}]\n"
            f"      trajectory: {{{trajectory}}}\n{extra}")


# The dark fragment on the grid (holey_grid_eb.pgm, centre) with the lattice around it.
def grid_fragment(data, x, y, phi=0.0, trajectory="static", extra=""):
    return (f"    - texture: {{path: {data}/holey_grid_eb.pgm, crop: [660, 570, 220, 260], mask: full}}\n"
            f"      size: [110, 130]\n"
            f"      start: [{x}, {y}, {phi}]\n"
            f"      trajectory: {{{trajectory}}}\n{extra}")


def grid_background(data):
    # 1:1 pixels: a 640x480 crop of the lattice's regular middle part.
    return f"  background: {{source: image, path: {data}/holey_grid_eb.pgm, crop: [420, 180, 640, 480]}}\n"


def chamber_background(data):
    # The dark chamber below the needle and left of the post (needle_lamella_post_eb.pgm), 1:1.
    return f"  background: {{source: image, path: {data}/needle_lamella_post_eb.pgm, crop: [0, 540, 640, 480]}}\n"


def post_background(data):
    # The bright post and its surroundings (needle_lamella_post_eb.pgm, right of the needle), 1:1.
    return f"  background: {{source: image, path: {data}/needle_lamella_post_eb.pgm, crop: [600, 300, 640, 480]}}\n"


SMOOTH = "kind: sine, amplitude_x_px: 60, amplitude_y_px: 30, amplitude_phi_deg: 15, period_s: 5"
WANDER = "kind: random_walk, sigma_px_per_sqrt_s: 12, sigma_deg_per_sqrt_s: 6, margin_px: 120"
LINEAR = "kind: linear, vx_px_s: 50, vy_px_s: 30, margin_px: 120"


class Seq:
    def __init__(self, name, dose, targets, background, easy_share=None, frames=60, effects="", seed=1,
                 what="", known="", pattern_background=None, mask=False):
        self.name, self.dose, self.targets, self.background = name, dose, targets, background
        self.easy_share, self.frames, self.effects, self.seed, self.what = easy_share, frames, effects, seed, what
        # known: a failure this check found in the pose engine and left to its owner (README, Known
        # limitations); printed as KNOWN and not failing the run unless --strict.
        self.known = known
        # The background the pattern is recorded over (None: the sequence's own): an operator
        # records it where the background is plain and then moves the target over the lattice.
        self.pattern_background = pattern_background
        self.mask = mask  # give replay the operator's mask of each pattern (write_mask)


def sequences(data):
    """The held-out sequences. easy_share: the TRACKING share an easy sequence must reach (None:
    a hard one, where only the no-false rule holds)."""
    s = []
    nl = lambda traj, extra="", brightness=1.3: [(lambda *a: needle_lamella(*a, brightness=brightness), 320, 240, 0.0,
                                                  traj, extra)]
    grid, chamber, post = grid_background(data), chamber_background(data), post_background(data)
    # Easy: the needle carrying its lamella over the dark chamber of its own micrograph.
    for dose, share in ((20, 0.9), (6, 0.9), (2.5, 0.8), (1, None)):
        s.append(Seq(f"needle_smooth_d{dose:g}", dose, nl(SMOOTH), chamber, share,
                     what="needle carrying its lamella on a figure eight over the dark chamber"))
    s.append(Seq("needle_line_d2.5", 2.5, nl(LINEAR), chamber, 0.8, seed=7, what="straight line, bouncing"))
    s.append(Seq("needle_line_d1", 1, nl(LINEAR), chamber, None, seed=7, what="the same at 1 e-/px"))
    s.append(Seq("needle_wander_d6", 6, nl(WANDER), chamber, 0.9, seed=3, what="random walk"))
    s.append(Seq("needle_scale_up_d6", 6, nl(SMOOTH, "      scale: {from: 1, to: 1.25, start_s: 0.5, ramp_s: 3}\n"),
                 chamber, 0.8, what="magnification ramp to +25 %"))
    s.append(Seq("needle_scale_down_d6", 6, nl(SMOOTH, "      scale: {from: 1, to: 0.75, start_s: 0.5, ramp_s: 3}\n"),
                 chamber, 0.8, what="magnification ramp to -25 %"))
    s.append(Seq("needle_charge_defocus_d6", 6, nl(SMOOTH), chamber, 0.7,
                 effects="  charging: {gain: {from: 1, to: 0.65, start_s: 1, ramp_s: 2}, offset: {from: 0, to: 0.08, start_s: 1, ramp_s: 2}}\n"
                         "  defocus_px: {from: 0, to: 1.5, start_s: 1, ramp_s: 2}\n",
                 what="charging (gain 1 -> 0.65, offset +0.08) and defocus (0 -> 1.5 px)"))
    s.append(Seq("needle_bandwidth_d2.5", 2.5, nl(SMOOTH), chamber, 0.6, effects="  detector_tau_ns: 250\n",
                 what="detector low-pass, tau = 1 px"))
    two = [(lambda *a: needle_lamella(*a), 200, 150, 0.0, SMOOTH, ""), (grid_fragment, 450, 330, 0.0, WANDER, "")]
    s.append(Seq("two_targets_d6", 6, two, chamber, 0.8, what="needle+lamella and the grid's fragment"))
    s.append(Seq("two_targets_d1", 1, two, chamber, None, what="the same at 1 e-/px"))
    # Hard: what a rigid pattern cannot always tell apart; only the no-false rule holds.
    # The pattern recorded over the plain chamber (with the operator's mask), the needle then moved
    # over the hole lattice: look-alikes all around, none in the pattern.
    for dose in (6, 2.5):
        s.append(Seq(f"needle_over_grid_d{dose:g}", dose, nl(SMOOTH), grid, None, pattern_background=chamber,
                     mask=True, what="pattern and mask over the chamber, tracked over the hole lattice"))
    s.append(Seq("needle_pattern_on_grid_d20", 20, nl(SMOOTH), grid, None,
                 what="the pattern recorded over the lattice itself"))
    s.append(Seq("needle_pattern_on_grid_d6", 6, nl(SMOOTH), grid, None,
                 what="the same at 6 e-/px"))
    s.append(Seq("faint_needle_over_grid_d6", 6, nl(SMOOTH, brightness=1.0), grid, None,
                 what="the needle at its own brightness, pattern over the lattice: the lattice fills most of it"))
    s.append(Seq("needle_over_post_d6", 6, nl(LINEAR, brightness=1.0), post, None,
                 what="the needle over the bright post: little contrast"))
    s.append(Seq("lattice_patch_over_lattice_d6", 6, [(lattice_patch, 320, 240, 0.0, LINEAR, "")], grid, None,
                 what="a lattice patch over the lattice: look-alikes one period away"))
    s.append(Seq("lattice_patch_over_lattice_d2.5", 2.5, [(lattice_patch, 320, 240, 0.0, SMOOTH, "")], grid, None,
                 what="the same at 2.5 e-/px, figure eight"))
    return s


def scene_yaml(seq, data, still):
    lines = [f"scan: {{field_w: {FIELD_W}, field_h: {FIELD_H}, max_roi_w: 256, max_roi_h: 256, "
             f"min_dwell_ns: 100, max_dwell_ns: 4000}}\n",
             "sim:\n", f"  seed: {seq.seed}\n", f"  beam_current_pa: {beam_pa(seq.dose):.4f}\n", f"  yield: {YIELD}\n",
             seq.pattern_background if still and seq.pattern_background else seq.background]
    if not still:
        lines.append(seq.effects)
    lines.append("  targets:\n")
    for build, x, y, phi, traj, extra in seq.targets:
        lines.append(build(data, x, y, phi, "kind: static" if still else traj, "" if still else extra))
    return "".join(lines)


def read_pgm(path):
    with open(path, "rb") as f:
        d = f.read()
    fields, i = [], 2
    while len(fields) < 3:
        while d[i:i + 1].isspace():
            i += 1
        if d[i:i + 1] == b"#":
            i = d.index(b"\n", i)
            continue
        j = i
        while not d[j:j + 1].isspace():
            j += 1
        fields.append(int(d[i:j]))
        i = j
    w, h, maxval = fields
    i += 1
    if maxval > 255:
        return w, h, [(d[i + 2 * k] << 8) | d[i + 2 * k + 1] for k in range(w * h)]
    return w, h, list(d[i:i + w * h])


def write_mask(pattern, out):
    """The operator's mask for a pattern recorded over a plain dark background: the target's
    pixels are the bright ones. Otsu's threshold on the pattern smoothed by a 5x5 box; 255 above."""
    w, h, px = read_pgm(pattern)
    sm = [0.0] * (w * h)
    for y in range(h):
        for x in range(w):
            acc = n = 0
            for yy in range(max(0, y - 2), min(h, y + 3)):
                for xx in range(max(0, x - 2), min(w, x + 3)):
                    acc += px[yy * w + xx]
                    n += 1
            sm[y * w + x] = acc / n
    lo, hi = min(sm), max(sm)
    bins = [0] * 256
    for v in sm:
        bins[min(255, int(255 * (v - lo) / max(1e-9, hi - lo)))] += 1
    total, sum_all = len(sm), sum(i * b for i, b in enumerate(bins))
    best, thr, w0, s0 = -1.0, 128, 0, 0.0
    for t in range(256):
        w0 += bins[t]
        s0 += t * bins[t]
        if w0 == 0 or w0 == total:
            continue
        m0, m1 = s0 / w0, (sum_all - s0) / (total - w0)
        between = w0 * (total - w0) * (m0 - m1) ** 2
        if between > best:
            best, thr = between, t
    level = lo + (thr + 0.5) * (hi - lo) / 255
    with open(out, "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (w, h) + bytes(255 if v > level else 0 for v in sm))


def run(cmd, log, timeout):
    t0 = time.monotonic()
    try:
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout, text=True)
    except subprocess.TimeoutExpired:
        log.append(f"TIMEOUT after {timeout} s: {' '.join(cmd)}")
        return None, time.monotonic() - t0, ""
    log.append(f"$ {' '.join(cmd)}\n{p.stdout}")
    if p.returncode < 0:
        log.append(f"CRASH: signal {-p.returncode}")
    return p.returncode, time.monotonic() - t0, p.stdout


def angle_diff(a, b, order=1):
    """|a - b| in degrees modulo 360/order: the pose declares its angle known modulo that
    (poses.csv angle_order, a target that looks the same turned by 360/order; 1 when not said)."""
    turn = 360.0 / order
    return abs((a - b + 1.5 * turn) % turn - 0.5 * turn)


def evaluate(seq, poses_csv, truth_csv):
    truth = {}
    with open(truth_csv) as f:
        for r in csv.DictReader(f):
            truth[(int(r["frame"]), int(r.get("target") or 0))] = (float(r["x_px"]), float(r["y_px"]), float(r["phi_deg"]))
    phi0 = {i: t[3] for i, t in enumerate(seq.targets)}
    per = {i: {"poses": 0, "tracking": 0, "false": 0, "sq_px": 0.0, "sq_deg": 0.0, "worst": None, "uncertain": 0}
           for i in range(len(seq.targets))}
    with open(poses_csv) as f:
        for r in csv.DictReader(f):
            t = int(r.get("target") or 0)
            frame = int(r["frame"])
            p = per[t]
            p["poses"] += 1
            if r["status"] == "UNCERTAIN":
                p["uncertain"] += 1
            if r["status"] != "TRACKING":
                continue
            p["tracking"] += 1
            tr = truth.get((frame, t))
            if tr is None:  # TRACKING where the truth says the target is not in the field
                p["false"] += 1
                p["worst"] = (frame, float("inf"), float("inf"), r["score"])
                continue
            dx = math.hypot(float(r["x_px"]) - tr[0], float(r["y_px"]) - tr[1])
            da = angle_diff(float(r["phi_deg"]), tr[2] - phi0[t], int(r.get("angle_order") or 1))
            p["sq_px"] += dx * dx
            p["sq_deg"] += da * da
            if dx > FALSE_PX or da > FALSE_DEG:
                p["false"] += 1
                if p["worst"] is None or dx > p["worst"][1]:
                    p["worst"] = (frame, dx, da, r["score"])
    return per


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sempose", required=True)
    ap.add_argument("--data", required=True, help="the folder holding the held-out images (config/data/sem)")
    ap.add_argument("--only", default="", help="comma-separated sequence names (substring match)")
    ap.add_argument("--keep", default="", help="keep the recordings and poses in this folder")
    ap.add_argument("--timeout", type=float, default=120, help="seconds per command")
    ap.add_argument("--strict", action="store_true", help="known failures fail the run too")
    args = ap.parse_args()
    data = os.path.abspath(args.data)
    for img in ("needle_lamella_post_eb.pgm", "holey_grid_eb.pgm"):
        if not os.path.isfile(os.path.join(data, img)):
            print(f"heldout: {data}/{img} is missing")
            return 2
    work = args.keep or tempfile.mkdtemp(prefix="sempose_heldout_")
    os.makedirs(work, exist_ok=True)
    seqs = [s for s in sequences(data) if not args.only or any(o in s.name for o in args.only.split(","))]
    print(f"held-out check: {len(seqs)} sequences, {FIELD_W}x{FIELD_H} field, {DWELL_NS} ns dwell, pattern 128^2 "
          f"from 10 still frames at {PATTERN_DWELL_NS} ns, ROI 192^2; false = TRACKING > {FALSE_PX:g} px or > {FALSE_DEG:g} deg off")
    print(f"{'sequence':34s} {'dose':>4s} {'tgt':>3s} {'poses':>5s} {'trk%':>6s} {'unc%':>5s} {'false':>5s} "
          f"{'rms_px':>7s} {'rms_deg':>7s} {'us/pose':>7s} {'time_s':>6s}  verdict")
    failures, known = [], []
    low_poses = low_false = 0
    for seq in seqs:
        d = os.path.join(work, seq.name)
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        log = []
        for still in (True, False):
            with open(os.path.join(d, "still.yaml" if still else "scene.yaml"), "w") as f:
                f.write(scene_yaml(seq, data, still))
        with open(os.path.join(d, "track.yaml"), "w") as f:
            f.write(f"scan: {{field_w: {FIELD_W}, field_h: {FIELD_H}, max_roi_w: 256, max_roi_h: 256, "
                    f"min_dwell_ns: 100, max_dwell_ns: 4000}}\n")
        t0 = time.monotonic()
        steps = [[args.sempose, "sim", "--out", f"{d}/still", "--frames", "10", "--dwell", str(PATTERN_DWELL_NS),
                  "--config", f"{d}/still.yaml", "--seed", str(seq.seed + 100)]]
        patterns = []
        for i, (_, x, y, _, _, _) in enumerate(seq.targets):
            patterns.append(f"{d}/pattern{i}.pgm")
            steps.append([args.sempose, "pattern", "--frames", f"{d}/still", "--center", f"{x},{y}", "--size", "128",
                          "--average", "10", "--out", patterns[-1]])
        steps.append([args.sempose, "sim", "--out", f"{d}/rec", "--frames", str(seq.frames), "--dwell", str(DWELL_NS),
                      "--config", f"{d}/scene.yaml", "--seed", str(seq.seed)])
        replay = [args.sempose, "replay", "--frames", f"{d}/rec", "--config", f"{d}/track.yaml", "--truth",
                  f"{d}/rec/ground_truth.csv", "--out", f"{d}/poses.csv"]
        for p in patterns:
            replay += ["--pattern", p] + (["--mask", p.replace(".pgm", "_mask.pgm")] if seq.mask else [])
        steps.append(replay)
        ok, out = True, ""
        for cmd in steps:
            if cmd is replay and seq.mask:
                for p in patterns:
                    write_mask(p, p.replace(".pgm", "_mask.pgm"))
            rc, _, out = run(cmd, log, args.timeout)
            if rc != 0:
                ok = False
                break
        elapsed = time.monotonic() - t0
        with open(os.path.join(d, "log.txt"), "w") as f:
            f.write("\n".join(log))
        if not ok:
            print(f"{seq.name:34s} FAILED:\n{log[-1] if log else ''}")
            failures.append(f"{seq.name}: a command failed, crashed or hung")
            continue
        us = "-"
        for tok in out.split():
            if tok.startswith("compute_us_p50="):
                us = tok.split("=")[1]
        per = evaluate(seq, f"{d}/poses.csv", f"{d}/rec/ground_truth.csv")
        for t, p in per.items():
            n = max(1, p["poses"])
            trk = p["tracking"] / n
            rms_px = math.sqrt(p["sq_px"] / p["tracking"]) if p["tracking"] else float("nan")
            rms_deg = math.sqrt(p["sq_deg"] / p["tracking"]) if p["tracking"] else float("nan")
            verdict = []
            if seq.dose >= 2.5 and p["false"]:
                verdict.append(f"FAIL {p['false']} false (worst: frame {p['worst'][0]}, {p['worst'][1]:.1f} px, "
                               f"{p['worst'][2]:.1f} deg, score {p['worst'][3]})")
            if seq.dose < 2.5:
                low_poses += p["poses"]
                low_false += p["false"]
                if p["false"]:
                    verdict.append(f"{p['false']} false (worst: frame {p['worst'][0]}, {p['worst'][1]:.1f} px)")
            if seq.easy_share is not None and trk < seq.easy_share:
                verdict.append(f"FAIL tracked {100 * trk:.1f} % < {100 * seq.easy_share:.0f} %")
            if any(v.startswith("FAIL") for v in verdict):
                if seq.known and not args.strict:
                    verdict = [v.replace("FAIL", "KNOWN", 1) for v in verdict] + [f"({seq.known})"]
                    known.append(seq.name)
                else:
                    failures.append(f"{seq.name} target {t}: {'; '.join(verdict)}")
            elif seq.known:
                verdict.append(f"passes now: drop its known mark ({seq.known})")
            print(f"{seq.name:34s} {seq.dose:4g} {t:3d} {p['poses']:5d} {100 * trk:6.1f} "
                  f"{100 * p['uncertain'] / n:5.1f} {p['false']:5d} {rms_px:7.3f} {rms_deg:7.3f} {us:>7s} "
                  f"{elapsed:6.1f}  {'; '.join(verdict) or 'ok'}")
    if low_poses:
        share = low_false / low_poses
        line = f"1 e-/px: {low_false} false TRACKING of {low_poses} poses = {100 * share:.2f} % (rule: <= 1 %)"
        print(line)
        if share > 0.01:
            failures.append(line)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    if failures:
        print("held-out check FAILED:\n  " + "\n  ".join(failures))
        return 1
    if known:
        print(f"held-out check: passed, with known failures left to the pose engine: {', '.join(sorted(set(known)))}")
    else:
        print("held-out check: passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
