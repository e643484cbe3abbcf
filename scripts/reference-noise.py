"""How far a recording's reference poses scatter from scan to scan, by the three-cornered
hat: three estimates of every step between consecutive scans (the reference's, the
registered trajectory's, and a pairwise point-to-line ICP of the raw returns written
here, independent of isoline's code), whose pairwise differences' mean squares give
each estimate's own variance where their errors are independent:

    var(ref) = (ms(ref - est) + ms(ref - icp) - ms(est - icp)) / 2,  and alike.

Errors the registration and the ICP share (both read the same returns) move into the
reference's figure, so it is an upper bound where they correlate; a negative variance
(printed as a negative root) says the three are not independent enough to split.
Components in the earlier scan's frame: along its heading, sideways (cm) and heading
(degrees); for consecutive scans, and for stretches of 10 m of path (each estimate's
steps composed: the pairwise ICP's chain drifts, and the hat counts its drift as its
own). The RPE over 1 m of a trajectory scored against a reference that scatters by s
cm a step is at least about s where the scans are about a metre apart.

Usage: reference-noise.py FRAMES.ndjson ESTIMATE.tum   (FRAMES: the recording's scans
with the reference poses, as `isoline convert` writes them; ESTIMATE: one line a scan)
Prints one JSON object.
"""
import json
import math
import sys

import numpy as np
from scipy.spatial import cKDTree

import tum

# Returns used: within 20 m (a SICK's far returns are sparse and grazing).
MAX_RANGE = 20.0
# The ICP's pairing reach and the robust kernel's scale, metres: the returns' noise
# (about 1 cm) with the gap between neighbouring beams on a wall a few metres off.
REACH, KERNEL = 0.2, 0.02


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def between(a, b):
    """b in a's frame."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy, wrap(b[2] - a[2])])


def place(p, pose):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return p @ np.array([[c, s], [-s, c]]) + pose[:2]


def returns(frame):
    r = np.array([v if v is not None else np.nan for v in frame["ranges"]], float)
    a = frame["angle_min"] + frame["angle_increment"] * np.arange(len(r))
    ok = np.isfinite(r) & (r > frame.get("range_min", 0.0)) & (r < MAX_RANGE)
    return np.c_[r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])]


def icp(source, target, x, rounds=30):
    """The pose of `source`'s frame in `target`'s: Gauss-Newton on point-to-line
    residuals, the lines the target's six nearest returns' principal direction, a Huber
    kernel; from `x`."""
    tree = cKDTree(target)
    _, nb = tree.query(target, k=6)
    normals = np.array([np.linalg.eigh(np.cov(target[n].T))[1][:, 0] for n in nb])
    x = x.astype(float).copy()
    for _ in range(rounds):
        moved = place(source, x)
        d, j = tree.query(moved)
        m = d < REACH
        if m.sum() < 20:
            return None
        n = normals[j[m]]
        r = np.sum((moved[m] - target[j[m]]) * n, 1)
        c, s = math.cos(x[2]), math.sin(x[2])
        p = source[m]
        dr = np.c_[-s * p[:, 0] - c * p[:, 1], c * p[:, 0] - s * p[:, 1]]
        jac = np.c_[n, np.sum(n * dr, 1)]
        w = 1.0 / np.maximum(1.0, np.abs(r) / KERNEL)
        step = np.linalg.solve(jac.T @ (jac * w[:, None]), jac.T @ (w * r))
        x -= step
        if np.abs(step).max() < 1e-6:
            break
    x[2] = wrap(x[2])
    return x


def main():
    frames = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
    est = tum.read(sys.argv[2])
    if len(est) != len(frames):
        sys.exit(f"{len(frames)} frames but {len(est)} poses")
    # Each step three ways; None where the ICP failed.
    steps = []
    for a, b, ea, eb in zip(frames, frames[1:], est, est[1:]):
        p, q = returns(b), returns(a)
        if len(p) < 30 or len(q) < 30 or a.get("pose") is None or b.get("pose") is None:
            steps.append(None)
            continue
        r = between(a["pose"], b["pose"])
        x = icp(p, q, r)
        # An ICP that left the reference by more than its reach found other walls.
        if x is None or np.abs(x[:2] - r[:2]).max() > 0.5:
            steps.append(None)
            continue
        steps.append((r, between(ea, eb), x))

    def ms(u, v):
        d = np.array(u) - np.array(v)
        d[:, 2] = np.degrees([wrap(t) for t in d[:, 2]])
        return np.mean(d**2, 0)

    def root(v):
        scale = np.array([100.0, 100.0, 1.0])
        return [round(float(math.copysign(math.sqrt(abs(x)), x) * k), 2) for x, k in zip(v, scale)]

    def hat(triples):
        ref, mine, pair = zip(*triples)
        rm, rp, mp = ms(ref, mine), ms(ref, pair), ms(mine, pair)
        return {
            "pairs": len(triples),
            "rms_reference_vs_estimate": root(rm),
            "rms_reference_vs_icp": root(rp),
            "rms_estimate_vs_icp": root(mp),
            "reference": root((rm + rp - mp) / 2),
            "estimate": root((rm + mp - rp) / 2),
            "icp": root((rp + mp - rm) / 2),
        }

    out = {"units": "along cm, sideways cm, heading deg"}
    good = [s for s in steps if s is not None]
    out["step_m"] = round(float(np.median([math.hypot(*s[0][:2]) for s in good])), 2)
    out["step"] = hat(good)
    # Over 10 m of the reference's path: each estimate's steps composed (the ICP's chain
    # of pairwise steps drifts; the hat takes its drift as its own error), every stretch
    # whose steps all have an ICP.
    along = np.concatenate([[0.0], np.cumsum([
        math.hypot(*(np.array(b["pose"][:2]) - a["pose"][:2])) if a.get("pose") and b.get("pose") else 0.0
        for a, b in zip(frames, frames[1:])
    ])])
    far, j = [], 0
    for i in range(len(steps)):
        j = max(j, i)
        while j < len(steps) and along[j] - along[i] < 10.0:
            j += 1
        if j >= len(steps):
            break
        run = steps[i:j]
        if any(s is None for s in run):
            continue
        total = []
        for k in range(3):
            pose = np.zeros(3)
            for s in run:
                c, sn = math.cos(pose[2]), math.sin(pose[2])
                pose = pose + [c * s[k][0] - sn * s[k][1], sn * s[k][0] + c * s[k][1], s[k][2]]
            pose[2] = wrap(pose[2])
            total.append(pose)
        far.append(tuple(total))
    if far:
        out["over_10_m"] = hat(far)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
