#!/usr/bin/python3
"""make_sem_scene.py SCENE_DIR REF_DIR OUT_DIR

From `sempose sim` recordings of scene_sim.yaml: SCENE_DIR (noise: false, one frame: the
expected image) and REF_DIR (the same scene with the simulator's detector noise), writes to
OUT_DIR:
  sem_scene.pgm        the scene sem_emul serves (8-bit P5, the first frame of SCENE_DIR)
  sem_scene_truth.csv  its target's pose (ground_truth.csv of SCENE_DIR, first row)
  sem_electrons.env    SEM_ELECTRONS_WHITE: sem_emul's electrons per sample at white that give
                       the same signal-to-noise ratio as the simulator's frames. The simulator's
                       noise variance grows linearly with the grey level (Poisson electrons x a
                       Gamma gain, no offset): var = a*g, i.e. g/a effective electrons at grey g;
                       sem_emul gives electrons_white*g/255 Poisson electrons, so
                       electrons_white = 255/a. prepare_config.sh adds SEM_REF_DWELL_NS: the
                       dwell at which sem_emul gives that dose (it scales it with the dwell).
"""
import csv
import glob
import os
import sys

import numpy as np


def read_pgm(path):
    with open(path, "rb") as f:
        data = f.read()
    fields, i = [], 2
    while len(fields) < 3:
        while data[i:i + 1].isspace():
            i += 1
        if data[i:i + 1] == b"#":
            while data[i:i + 1] != b"\n":
                i += 1
            continue
        j = i
        while not data[j:j + 1].isspace():
            j += 1
        fields.append(int(data[i:j]))
        i = j
    w, h, maxval = fields
    i += 1
    dtype = np.uint8 if maxval < 256 else ">u2"
    return np.frombuffer(data[i:], dtype=dtype, count=w * h).reshape(h, w).astype(np.float64), maxval


def main():
    scene_dir, ref_dir, out = sys.argv[1:4]
    frames = sorted(glob.glob(os.path.join(scene_dir, "*.pgm")))
    scene, maxval = read_pgm(frames[0])
    if maxval != 255:
        sys.exit(f"make_sem_scene: {frames[0]} is not 8-bit")
    with open(os.path.join(out, "sem_scene.pgm"), "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (scene.shape[1], scene.shape[0]))
        f.write(scene.astype(np.uint8).tobytes())
    with open(os.path.join(scene_dir, "ground_truth.csv")) as f:
        row = next(csv.DictReader(f))
    with open(os.path.join(out, "sem_scene_truth.csv"), "w") as f:
        f.write("frame,x_px,y_px,phi_deg\n0,%s,%s,%s\n" % (row["x_px"], row["y_px"], row["phi_deg"]))
    refs = [read_pgm(p)[0] for p in sorted(glob.glob(os.path.join(ref_dir, "*.pgm")))]
    mask = (scene > 5) & (scene < 250)  # away from black and saturation
    var = np.mean([(r - scene) ** 2 for r in refs], axis=0)
    a = float(np.sum(var[mask]) / np.sum(scene[mask]))
    ew = max(1, round(255.0 / a))
    with open(os.path.join(out, "sem_electrons.env"), "w") as f:
        f.write(f"SEM_ELECTRONS_WHITE={ew}\n")
    print(f"[make_sem_scene] scene {scene.shape[1]}x{scene.shape[0]} mean grey {scene.mean():.1f}, truth "
          f"({row['x_px']}, {row['y_px']}, {row['phi_deg']}); simulator noise var = {a:.3f} x grey -> "
          f"electrons_white {ew} ({ew * scene[mask].mean() / 255:.1f} e- per pixel on average)")


if __name__ == "__main__":
    main()
