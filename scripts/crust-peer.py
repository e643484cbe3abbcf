#!/usr/bin/env python3
"""A graph over the samples as a peer on the glyph corpus, outside the build: the
direction the point-cloud issue suggests for strokes, measured before it is built.

Each case's samples, less the outliers isoline reports (its single-return features),
are moved onto their local line (moving least squares: each sample projected on the
principal axis of the samples within r, twice; r = 5 sigma, at least two spacings) and
thinned to half a spacing; then NN-crust (Dey & Kumar 1999) joins each sample to its
nearest and to its nearest on the other side (the half-neighbour). Scored as
scripts/glyphs.py scores strokes, against the same bound (3 sigma + 2 hmin, isoline's
hmin on the same points): the share of the truth's length farther than the bound from
every edge ("missed"), the share of the edges' length farther than the bound from the
truth ("off the truth"), and the graph's independent cycles (a stroke has none; a
closed outline one). isoline's own curves are scored the same way beside it.

sigma is the noise isoline measured on the case (its record's `stats.noise`); with
--oracle the case's true noise; with --plain the median over the samples of the
smaller principal deviation of their 16 nearest (a plain estimate, thrown off by
corners and crossings).

Usage: crust-peer.py DIR [--oracle | --plain]   (DIR: scripts/glyphs.sh's output directory)
"""
import collections
import json
import os
import sys

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
import glyphs  # noqa: E402


def crust(P):
    """NN-crust's edges over the points P: each to its nearest, and to its nearest
    whose direction is more than 90 degrees from that one's."""
    _, idx = cKDTree(P).query(P, min(12, len(P)))
    edges = set()
    for i in range(len(P)):
        q = idx[i, 1]
        edges.add((min(i, q), max(i, q)))
        v = P[q] - P[i]
        for r in idx[i, 2:]:
            if np.dot(P[r] - P[i], v) < 0:
                edges.add((min(i, r), max(i, r)))
                break
    return edges


def cycles(n, edges):
    """Independent cycles of the graph: edges that close a loop in a union-find."""
    parent = list(range(n))
    count = 0
    for a, b in edges:
        ra, rb = glyphs.root(parent, a), glyphs.root(parent, b)
        if ra == rb:
            count += 1
        else:
            parent[ra] = rb
    return count


def projected(P, sigma):
    """P moved twice onto the principal axis of its neighbours within r, then thinned
    to half a spacing."""
    tree = cKDTree(P)
    spacing = float(np.median(tree.query(P, 3)[0][:, 2]))
    if sigma > 0:
        r = max(5 * sigma, 2 * spacing)
        for _ in range(2):
            Q = P.copy()
            for i, near in enumerate(tree.query_ball_point(P, r)):
                if len(near) < 3:
                    continue
                X = P[near]
                m = X.mean(0)
                normal = np.linalg.eigh(np.cov((X - m).T))[1][:, 0]
                Q[i] = P[i] - np.dot(P[i] - m, normal) * normal
            P, tree = Q, cKDTree(Q)
    keep = np.ones(len(P), bool)
    for i in range(len(P)):
        if keep[i]:
            for j in tree.query_ball_point(P[i], 0.5 * spacing):
                if j > i:
                    keep[j] = False
    return P[keep]


def noise(P):
    """The median smaller principal deviation of each sample's 16 nearest."""
    _, near = cKDTree(P).query(P, min(16, len(P)))
    X = P[near] - P[near].mean(1, keepdims=True)
    C = np.einsum("nki,nkj->nij", X, X) / X.shape[1]
    return float(np.median(np.sqrt(np.maximum(np.linalg.eigvalsh(C)[:, 0], 0.0))))


def score(curves, truth, bound, step):
    """Missed and off-the-truth shares of `curves` against `truth`."""
    cd = glyphs.densify(curves, step)
    td = glyphs.densify(truth, step)
    if not len(cd):
        return 1.0, 0.0
    return (float((cKDTree(cd).query(td)[0] > bound).mean()),
            float((cKDTree(td).query(cd)[0] > bound).mean()))


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 1:
        sys.exit(__doc__)
    d, oracle, plain = args[0], "--oracle" in sys.argv, "--plain" in sys.argv
    if not os.path.isdir(d):
        print(f"no {d}: run scripts/glyphs.sh first", file=sys.stderr)
        sys.exit(0 if os.environ.get("QUICK") == "1" else 1)
    rows = collections.defaultdict(list)
    for name in sorted(os.listdir(d)):
        if not name.endswith(".case.json"):
            continue
        case = os.path.join(d, name[: -len(".case.json")])
        c = json.load(open(case + ".case.json"))
        truth = json.load(open(case + ".truth.json"))["polylines"]
        P = np.array(json.loads(open(case + ".ndjson").readline())["points"])
        try:
            rec = json.loads(open(case + ".recon.ndjson").readline())
        except (OSError, ValueError):
            continue
        hmin = rec["stats"]["hmin"]
        bound = 3 * c["sigma"] + 2 * hmin
        lone = [f["center"] for f in rec.get("features", []) if f.get("returns") == 1]
        if lone:
            kept = cKDTree(np.array(lone)).query(P)[0] > 1e-12
            if kept.sum() >= 10:
                P = P[kept]
        if oracle:
            sigma = c["sigma"]
        elif plain or "noise" not in rec["stats"]:
            sigma = noise(P)
        else:
            sigma = rec["stats"]["noise"]
        Q = projected(P, sigma)
        edges = crust(Q)
        segs = [{"closed": False, "points": [Q[a].tolist(), Q[b].tolist()]} for a, b in edges]
        ours = score(rec["polylines"], truth, bound, hmin / 4)
        peer = score(segs, truth, bound, hmin / 4)
        key = ("font outlines" if c["kind"] == "outline" else "Hershey strokes",
               "5%" if c["outliers"] > 0 else "none")
        rows[key].append(ours + peer + (cycles(len(Q), edges),))
    print("| shapes | outliers | cases | isoline: missed, off the truth | graph over the samples: missed, off the truth | its cycles, median |")
    print("|---|---:|---:|---:|---:|---:|")
    for (shapes, out), v in sorted(rows.items(), key=lambda kv: (kv[0][0] != "font outlines", kv[0][1] != "none")):
        a = np.array(v)
        print(f"| {shapes} | {out} | {len(a)} | {100 * a[:, 0].mean():.2f}%, {100 * a[:, 1].mean():.2f}% "
              f"| {100 * a[:, 2].mean():.2f}%, {100 * a[:, 3].mean():.2f}% | {np.median(a[:, 4]):.0f} |")


if __name__ == "__main__":
    main()
