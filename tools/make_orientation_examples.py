#!/usr/bin/env python3
"""Writes the example position tables of docs/examples: a 6-position flip test and a 24-position
tumble test of one simulated device, as position tables with f_x,f_y,f_z (docs/design.md section
6), outputs in raw counts; and gimbal12.csv, a gimbal run of the same device (12 positions per
phase, outputs in m/s^2) with a small quadratic non-linearity of v for the analysis to find
(docs/finding_the_missing_effect.md). Independent of the C++ simulator: numpy draws the
samples of each dwell from R = K (S g f + O) + noise, K counts per m/s^2.

    /usr/bin/python3 tools/make_orientation_examples.py docs/examples
"""
import os
import sys

import numpy as np

G = 9.80665
COUNTS_PER_MS2 = 1000.0  # a 16-bit part at +-32 m/s^2 full scale
S = np.array([[1.012, 0.004, -0.009], [-0.003, 0.991, 0.011], [0.006, -0.007, 1.004]])
O = np.array([0.12, -0.05, 0.2])  # m/s^2
NOISE = 0.02  # m/s^2 per sample
SAMPLES = 500
RATE_HZ = 100.0
HEADER = ("phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w,"
          "f_x,f_y,f_z")


def six_positions():
    return [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]


def tumble24():
    """12 edge, 8 corner and 4 face directions of a cube."""
    d = []
    for a in range(3):
        for s1 in (-1, 1):
            for s2 in (-1, 1):
                v = [0, 0, 0]
                v[(a + 1) % 3] = s1
                v[(a + 2) % 3] = s2
                d.append(tuple(v))
    d += [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    d += [(1, 0, 0), (-1, 0, 0), (0, 0, 1), (0, 0, -1)]
    return d


def write(path, directions, seed):
    rng = np.random.default_rng(seed)
    t = 0.0
    with open(path, "w") as out:
        out.write("# Simulated by tools/make_orientation_examples.py (numpy), outputs in counts.\n")
        out.write("# truth: counts_per_ms2=%g g=%.5f\n" % (COUNTS_PER_MS2, G))
        for s in range(3):
            out.write("# truth: S_%s=%s O_%s=%r\n" % ("uvw"[s], ",".join(repr(x) for x in S[s]),
                                                      "uvw"[s], O[s]))
        out.write(HEADER + "\n")
        for i, d in enumerate(directions):
            f = np.array(d, dtype=float)
            f /= np.linalg.norm(f)
            true = COUNTS_PER_MS2 * (S @ (G * f) + O)
            samples = true + COUNTS_PER_MS2 * NOISE * rng.standard_normal((SAMPLES, 3))
            mean = samples.mean(axis=0)
            std = samples.std(axis=0, ddof=1)
            t_end = t + SAMPLES / RATE_HZ
            out.write("-,%d,,%.3f,%.3f,%d,%s,%s,%s\n" % (
                i, t, t_end, SAMPLES, ",".join(repr(x) for x in mean),
                ",".join(repr(x) for x in std), ",".join(repr(x) for x in f)))
            t = t_end + 20.0  # turning the block over by hand


GIMBAL_STEPS = 12
K2_V = 6e-5  # quadratic non-linearity of v, 1/(m/s^2): R_v += K2 L_v^2 / |v|


def gimbal_direction(phase, a):
    """Specific force per g in the DUT frame (docs/design.md section 1)."""
    if phase == "x":
        return np.array([0.0, np.sin(a), np.cos(a)])
    if phase == "y":
        return np.array([np.sin(a), 0.0, np.cos(a)])
    return np.array([np.sin(a), np.cos(a), 0.0])


def write_gimbal(path, seed):
    rng = np.random.default_rng(seed)
    t = 10.0
    with open(path, "w") as out:
        out.write("# Simulated by tools/make_orientation_examples.py (numpy), outputs in m/s^2.\n")
        out.write("# truth: g=%.5f quadratic_nonlinearity[v]=%g\n" % (G, K2_V))
        for s in range(3):
            out.write("# truth: S_%s=%s O_%s=%r\n" % ("uvw"[s], ",".join(repr(x) for x in S[s]),
                                                      "uvw"[s], O[s]))
        out.write(HEADER.rsplit(",f_x", 1)[0] + "\n")
        for phase in "xyz":
            for n in range(GIMBAL_STEPS):
                a = 2.0 * np.pi * n / GIMBAL_STEPS
                f = G * gimbal_direction(phase, a)
                true = S @ f + O
                true[1] += K2_V * (S[1] @ f) ** 2 / np.linalg.norm(S[1])
                samples = true + NOISE * rng.standard_normal((SAMPLES, 3))
                mean = samples.mean(axis=0)
                std = samples.std(axis=0, ddof=1)
                t_end = t + SAMPLES / RATE_HZ
                out.write("%s,%d,%r,%.3f,%.3f,%d,%s,%s\n" % (
                    phase, n, a, t, t_end, SAMPLES, ",".join(repr(x) for x in mean),
                    ",".join(repr(x) for x in std)))
                t = t_end + 1.5  # the move to the next position
            t += 5.0  # the change of phase


def main():
    outdir = sys.argv[1] if len(sys.argv) > 1 else "docs/examples"
    os.makedirs(outdir, exist_ok=True)
    write(os.path.join(outdir, "six_position.csv"), six_positions(), 6)
    write(os.path.join(outdir, "tumble24.csv"), tumble24(), 24)
    write_gimbal(os.path.join(outdir, "gimbal12.csv"), 12)


if __name__ == "__main__":
    main()
