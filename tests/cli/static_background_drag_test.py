#!/usr/bin/python3
"""A target moving out of its pattern's static background (hostile round 13, outside-made scenes).

The needle tip of needle_contact_eb.pgm (masked, half size) is composited over another region of a
real micrograph and moves 1 px a frame along its axis. Its pattern is made the operator's way (10
still frames at 20 e-/px, `sempose pattern`), so it holds the background under the needle. Where
that background is textured it holds the pose while the needle drags it a little: before the
tiles' check (split_consistency.hpp, Tracker::Impl::parts_doubted) 16 of 25 poses were TRACKING
5-16 px behind the needle at 20 e-/px (the first noise draw; 0 on the next two), and 18 at 6 e-/px.
Asserted: 0 such poses at 20 e-/px on three noise draws. Printed, not asserted: 6 e-/px, where the
tiles see the drag on some draws only (0 / 17 / 2 poses on draws 1-3; README Known limitations).
Over a smooth background (the control) the pose follows the needle, TRACKING.

usage: static_background_drag_test.py SEMPOSE SOURCE_DIR   (python3-numpy; exit 1 on a failure)
"""
import csv
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

SEMPOSE, SRC = sys.argv[1], sys.argv[2]


def read_pgm(path):
    data = open(path, 'rb').read()
    fields, i = [], 0
    while len(fields) < 4:
        while data[i:i + 1].isspace():
            i += 1
        if data[i:i + 1] == b'#':
            while data[i:i + 1] not in (b'\n', b''):
                i += 1
            continue
        j = i
        while not data[j:j + 1].isspace():
            j += 1
        fields.append(data[i:j])
        i = j
    w, h = int(fields[1]), int(fields[2])
    return np.frombuffer(data[i + 1:], dtype=np.uint8, count=w * h).reshape(h, w) / 255.0


def write_pgm(path, img):
    h, w = img.shape
    with open(path, 'wb') as f:
        f.write(b'P5\n%d %d\n255\n' % (w, h))
        f.write(np.clip(np.round(img), 0, 255).astype(np.uint8).tobytes())


def blur(img, s):
    r = int(math.ceil(3.5 * s))
    k = np.exp(-np.arange(-r, r + 1) ** 2 / (2 * s * s))
    k /= k.sum()
    p = np.pad(img, r, mode='edge')
    t = sum(kv * p[:, i:i + img.shape[1]] for i, kv in enumerate(k))
    return sum(kv * t[i:i + img.shape[0], :] for i, kv in enumerate(k))


def bilinear(img, u, v):
    h, w = img.shape
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = u - u0, v - v0
    inside = (u0 >= 0) & (v0 >= 0) & (u0 < w - 1) & (v0 < h - 1)
    uc, vc = np.clip(u0, 0, w - 2), np.clip(v0, 0, h - 2)
    out = (img[vc, uc] * (1 - fu) * (1 - fv) + img[vc, uc + 1] * fu * (1 - fv) + img[vc + 1, uc] * (1 - fu) * fv +
           img[vc + 1, uc + 1] * fu * fv)
    return np.where(inside, out, 0.0)


def half(img):
    img = blur(img, 1.0)
    v, u = np.mgrid[0:img.shape[0] // 2, 0:img.shape[1] // 2].astype(float)
    return bilinear(img, 2 * u + 0.5, 2 * v + 0.5)


def needle():
    """The needle's cone from needle_contact_eb.pgm at half size: texture, opacity, pose point."""
    src = read_pgm(os.path.join(SRC, 'config/data/sem/needle_contact_eb.pgm'))
    x0, y0, x1, y1 = 380, 380, 700, 660
    tex = src[y0:y1, x0:x1]
    yy, xx = np.mgrid[y0:y1, x0:x1]
    up, lo = 345 + 125 * xx / 668.0, 700 - 140 * xx / 668.0  # the cone's edges
    a = ((blur(tex, 3) > 0.55) & (yy > up - 25) & (yy < lo + 25) & (xx < 676)).astype(float)
    a = (blur((blur(a, 3) > 0.15).astype(float), 3) > 0.85).astype(float)
    a[xx < 560] = np.maximum(a[xx < 560], ((yy > up + 15) & (yy < lo - 15))[xx < 560])
    return half(tex), np.clip(half(blur(a, 1.0)), 0, 1), ((620 - x0) / 2, (515 - y0) / 2)


def frame(bg, tex, alpha, anchor, x, y, dose, rng):
    v, u = np.mgrid[0:bg.shape[0], 0:bg.shape[1]].astype(float)
    a = bilinear(alpha, u - x + anchor[0], v - y + anchor[1])
    img = blur(bg * (1 - a) + bilinear(tex, u - x + anchor[0], v - y + anchor[1]) * a, 0.8)
    return np.clip((0.04 + 0.85 * rng.poisson(img * dose) / dose) * 255, 0, 255)


def record(folder, frames, truth=None):
    os.makedirs(folder)
    with open(os.path.join(folder, 'frames.csv'), 'w') as f:
        f.write('frame,t_ns\n')
        for i, img in enumerate(frames):
            f.write('%d,%d\n' % (i, 1_000_000_000 + i * 100_000_000))
            write_pgm(os.path.join(folder, 'frame_%06d.pgm' % i), img)
    if truth:
        with open(os.path.join(folder, 'truth.csv'), 'w') as f:
            f.write('frame,x_px,y_px,phi_deg\n')
            f.writelines('%d,%.4f,%.4f,0\n' % (i, x, y) for i, (x, y) in enumerate(truth))


def run_case(work, name, bg_region, dose, seed=1):
    src = read_pgm(os.path.join(SRC, 'config/data/sem/%s.pgm' % bg_region[0]))
    bx, by = bg_region[1], bg_region[2]
    bg = src[by:by + 480, bx:bx + 636]
    tex, alpha, anchor = needle()
    d = os.path.join(work, name)
    still = np.random.default_rng(99)
    record(os.path.join(d, 'still'), [frame(bg, tex, alpha, anchor, 320, 240, 20, still) for _ in range(10)])
    pattern = os.path.join(d, 'pattern.pgm')
    subprocess.run([SEMPOSE, 'pattern', '--frames', os.path.join(d, 'still'), '--center', '320,240', '--out', pattern],
                   check=True, capture_output=True)
    truth = [(320 + i, 240.0) for i in range(25)]
    rng = np.random.default_rng(seed)
    record(os.path.join(d, 'rec'), [frame(bg, tex, alpha, anchor, x, y, dose, rng) for x, y in truth], truth)
    with open(os.path.join(d, 'cfg.yaml'), 'w') as f:
        f.write('pipeline:\n  virtual_compute_ns: 300000\n')
    poses = os.path.join(d, 'poses.csv')
    subprocess.run([SEMPOSE, 'replay', '--frames', os.path.join(d, 'rec'), '--pattern', pattern, '--config',
                    os.path.join(d, 'cfg.yaml'), '--out', poses], check=True, capture_output=True)
    tracking = false = 0
    for row in csv.DictReader(open(poses)):
        if row['status'] != 'TRACKING':
            continue
        tracking += 1
        x, y = truth[int(row['frame'])]
        err = math.hypot(float(row['x_px']) - x, float(row['y_px']) - y)
        false += err > 3.0 or abs(float(row['phi_deg'])) > 10.0
    print('%s: TRACKING %d of 25, %d of them > 3 px or > 10 deg off' % (name, tracking, false))
    return tracking, false


def main():
    fails = 0
    with tempfile.TemporaryDirectory() as work:
        for seed in (1, 2, 3):
            _, false = run_case(work, 'textured_d20_draw%d' % seed, ('needle_contact_eb', 900, 500), 20, seed)
            if false:
                print('FAIL: TRACKING behind the needle, on its pattern\'s background (16 on draw 1 before)')
                fails += 1
        run_case(work, 'textured_d6_draw1_not_asserted', ('needle_contact_eb', 900, 500), 6)
        tracking, false = run_case(work, 'smooth_d6', ('lamella_on_post_eb', 700, 300), 6)
        if false or tracking < 20:
            print('FAIL: over a smooth background the needle is followed, TRACKING (24 of 25 before)')
            fails += 1
    print('static_background_drag: %s' % ('all passed' if not fails else '%d failed' % fails))
    return 1 if fails else 0


sys.exit(main())
