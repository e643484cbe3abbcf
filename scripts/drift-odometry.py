#!/usr/bin/env python3
"""Drifting wheel odometry made from a recording's reference poses, seeded.

Reads NDJSON frames (as `isoline convert` writes them) whose poses are a reference
(a SLAM system's corrected poses), and writes (1) the same frames with each pose
replaced by dead reckoning over corrupted step motions and (2) the reference as a TUM
trajectory (`t x y z qx qy qz qw`), for `isoline eval --trajectory`.

Each step's motion in the robot's frame (forward d, sideways s, turn a) is corrupted
the way wheels err (Borenstein & Feng 1996, "UMBmark"): systematically, a scale error
on distance (unequal wheel diameters' mean, drawn once per run within +-SCALE) and a
heading bias per metre (a wrong wheel base, drawn once per run within +-BIAS deg/m);
randomly, Gaussian noise of NOISE_T of each step's length on translation and
NOISE_R of its turn plus NOISE_RM deg per metre on heading.

Usage: drift-odometry.py IN.ndjson OUT.ndjson REF.tum SEED
"""
import json
import math
import random
import sys

SCALE = 0.02
BIAS = 1.0
NOISE_T = 0.02
NOISE_R = 0.02
NOISE_RM = 0.3


def between(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return [c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2])]


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2])]


def wrap(t):
    return (t + math.pi) % (2 * math.pi) - math.pi


def tum(t, p):
    return f"{t:.6f} {p[0]:.6f} {p[1]:.6f} 0 0 0 {math.sin(p[2] / 2):.9f} {math.cos(p[2] / 2):.9f}\n"


def main():
    src, out, ref, seed = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    rng = random.Random(seed)
    scale = rng.uniform(-SCALE, SCALE)
    bias = math.radians(rng.uniform(-BIAS, BIAS))
    prev_ref = odom = None
    with open(src) as f, open(out, "w") as o, open(ref, "w") as r:
        r.write("# t x y z qx qy qz qw\n")
        for line in f:
            frame = json.loads(line)
            pose = frame.get("pose")
            if pose is None:
                o.write(line)
                continue
            t = frame.get("t", frame.get("frame", 0))
            r.write(tum(t, pose))
            if prev_ref is None:
                odom = list(pose)
            else:
                d = between(prev_ref, pose)
                length = math.hypot(d[0], d[1])
                step = [
                    d[0] * (1 + scale) + rng.gauss(0, NOISE_T * length),
                    d[1] * (1 + scale) + rng.gauss(0, NOISE_T * length),
                    d[2]
                    + bias * length
                    + rng.gauss(0, NOISE_R * abs(d[2]) + math.radians(NOISE_RM) * length),
                ]
                odom = compose(odom, step)
            prev_ref = pose
            frame["pose"] = odom
            o.write(json.dumps(frame, separators=(",", ":")) + "\n")


if __name__ == "__main__":
    main()
