#!/usr/bin/env python3
"""A development corpus of point clouds that is not the tests: glyphs.

Shapes are the outlines of the TrueType fonts Debian ships (closed curves with holes,
narrow counters, sharp corners; read with fontTools), the Hershey stroke fonts (open
strokes, T-junctions, crossings; Debian's hershey-fonts-data) and procedural shapes the
fonts lack (spirals whose turns run close, their bands' outlines, combs with narrow
slots, rings with a narrow gap; scored with the outlines or the strokes by their kind).
Each case samples one shape at a density, a noise level (up to 1% of the shape's size),
a sampling (uniform, or a density varying 5-fold along the curves) and with or without
5% outliers, all drawn from the case's seed. Shapes and seeds are split: a shape belongs to the development part or
to the test part by a hash of its name, and development seeds are 0..99_999, test seeds
100_000 and up, so that tuning on one part never sees the other.

    glyphs.py make DIR --part dev|test --cases N     # frames and truths in DIR
    glyphs.py score DIR [--peer cgal]                # one JSON line a case, then a summary
    glyphs.py edges DIR                              # CGAL's edges as result records

`make` writes DIR/<case>.ndjson (one frame of points), DIR/<case>.truth.json (the shape's
curves, `isoline synth`'s truth format) and DIR/<case>.case.json (what was drawn).
`score` reads DIR/<case>.recon.ndjson (isoline's record) beside them, or with `--peer
cgal` DIR/<case>.cgal.ndjson: CGAL's optimal-transport edges (DIR/<case>.edges, its
milliseconds in DIR/<case>.cgal-ms) chained into polylines by `edges`, scored by the same
rules against the same bound (isoline's hmin on the same points).
"""

import argparse
import concurrent.futures
import glob
import hashlib
import json
import math
import os
import random
import sys

import numpy as np
from scipy.spatial import cKDTree

FONT_DIR = "/usr/share/fonts/truetype"
# The outline families the corpus reads (Debian's fonts-dejavu-core, fonts-dejavu-extra
# and fonts-liberation, which scripts/tools.sh installs): other fonts a machine happens
# to have would change the corpus and its split.
FONT_FAMILIES = ("DejaVu", "Liberation")
HERSHEY_DIR = "/usr/share/hershey-fonts"
# Hershey fonts of strokes (the symbol sets hold markers and music, not drawings).
HERSHEY_FONTS = [
    "futural", "futuram", "rowmans", "rowmand", "rowmant", "scripts", "scriptc",
    "cursive", "timesr", "timesi", "greek", "greekc", "cyrillic", "gothiceng",
]
CHARS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789&%@$#?"
# Noise per coordinate: none, 0.25%, 0.6% and 1% of the shapes' size (0.8 of the box).
NOISES = [0.0, 0.002, 0.005, 0.008]
DENSITIES = [1000, 2000, 4000]
OUTLIERS = 0.05
# Samplings: uniform by arc length, or with a density that varies smoothly along the
# curves by a factor of NONUNIFORM between the densest and the sparsest stretch.
SAMPLINGS = ["uniform", "nonuniform"]
NONUNIFORM = 5.0
TEST_SEEDS = 100_000


def part_of(name):
    """A third of the shapes are for development, by a hash of the name."""
    h = int(hashlib.sha256(name.encode()).hexdigest()[:8], 16)
    return "dev" if h % 3 == 0 else "test"


def flatten_font(path):
    """Every glyph of CHARS in one TrueType font: its contours as closed polylines."""
    from fontTools.pens.basePen import BasePen
    from fontTools.ttLib import TTFont

    class Flat(BasePen):
        def __init__(self, glyphs):
            super().__init__(glyphs)
            self.contours, self.cur = [], []

        def _moveTo(self, p):
            self.cur = [p]

        def _lineTo(self, p):
            self.cur.append(p)

        def _curveToOne(self, a, b, c):
            p0 = self.cur[-1]
            for i in range(1, 13):
                t = i / 12
                s = 1 - t
                self.cur.append(tuple(s**3 * p0[k] + 3 * s * s * t * a[k] + 3 * s * t * t * b[k] + t**3 * c[k] for k in (0, 1)))

        def _qCurveToOne(self, a, b):
            p0 = self.cur[-1]
            for i in range(1, 9):
                t = i / 8
                s = 1 - t
                self.cur.append(tuple(s * s * p0[k] + 2 * s * t * a[k] + t * t * b[k] for k in (0, 1)))

        def _closePath(self):
            if len(self.cur) > 2:
                self.contours.append(self.cur)
            self.cur = []

        _endPath = _closePath

    font = TTFont(path, lazy=True)
    cmap = font.getBestCmap()
    glyphs = font.getGlyphSet()
    out = {}
    for ch in CHARS:
        name = cmap.get(ord(ch))
        if name is None:
            continue
        pen = Flat(glyphs)
        glyphs[name].draw(pen)
        if pen.contours:
            out[ch] = [{"closed": True, "points": dedup(c)} for c in pen.contours]
    return out


def read_hershey(path):
    """Every glyph of a Hershey .jhf font: its strokes as open polylines (y up)."""
    text = open(path, encoding="latin-1").read().split("\n")
    glyphs, i = [], 0
    while i < len(text):
        line = text[i]
        i += 1
        if len(line) < 10:
            continue
        n = int(line[5:8])
        # A glyph with many vertices continues on the next lines.
        while len(line) < 8 + 2 * n and i < len(text):
            line += text[i]
            i += 1
        coords = line[10 : 8 + 2 * n]
        strokes, cur = [], []
        for k in range(0, len(coords) - 1, 2):
            pair = coords[k : k + 2]
            if pair == " R":
                if len(cur) > 1:
                    strokes.append(cur)
                cur = []
            else:
                cur.append((ord(pair[0]) - ord("R"), -(ord(pair[1]) - ord("R"))))
        if len(cur) > 1:
            strokes.append(cur)
        glyphs.append(strokes)
    out = {}
    # The fonts hold ASCII from the space on, in order.
    for k, strokes in enumerate(glyphs):
        ch = chr(32 + k)
        if ch in CHARS and strokes:
            # A stroke that ends where it began (an o, a 0) is a closed curve.
            out[ch] = [
                {"closed": closed, "points": dedup(s, closed)}
                for s in strokes
                for closed in [len(s) > 3 and math.dist(s[0], s[-1]) <= 1e-9]
                if len(dedup(s, closed)) > 1
            ]
    return out


def dedup(points, closed=True):
    """Repeated points once; a closed curve's last point, when it repeats the first, goes."""
    out = []
    for p in points:
        if not out or math.dist(p, out[-1]) > 1e-9:
            out.append((float(p[0]), float(p[1])))
    if closed and len(out) > 2 and math.dist(out[0], out[-1]) <= 1e-9:
        out.pop()
    return out


def shapes():
    """Every shape of the corpus, by name, sorted: (name, kind, polylines)."""
    out = []
    for path in sorted(glob.glob(os.path.join(FONT_DIR, "**", "*.ttf"), recursive=True)):
        font = os.path.splitext(os.path.basename(path))[0]
        if not font.startswith(FONT_FAMILIES):
            continue
        for ch, pls in flatten_font(path).items():
            out.append((f"{font}:{ord(ch):x}", "outline", pls))
    for font in HERSHEY_FONTS:
        path = os.path.join(HERSHEY_DIR, font + ".jhf")
        if os.path.exists(path):
            for ch, pls in read_hershey(path).items():
                if pls:
                    out.append((f"hershey-{font}:{ord(ch):x}", "strokes", pls))
    return sorted(out, key=lambda s: s[0]) + procedural()


def spiral_points(turns, inner, k=64):
    """An Archimedean spiral from radius `inner` to 1 over `turns` turns, k points a turn."""
    n = int(turns * k) + 1
    th = np.linspace(0.0, 2 * math.pi * turns, n)
    r = inner + (1.0 - inner) * th / th[-1]
    return np.stack([r * np.cos(th), r * np.sin(th)], axis=1)


def procedural():
    """Shapes the fonts lack, by name: spirals whose turns run close (narrow channels
    between open strokes, a centre), their bands' outlines, combs (outlines with narrow
    slots) and rings with a narrow gap between two loops."""
    out = []
    for turns in (1.5, 2, 2.5, 3, 4, 5):
        for inner in (0.05, 0.3, 0.5, 0.7):
            p = spiral_points(turns, inner)
            out.append((f"proc-spiral:{turns}:{inner}", "strokes", [{"closed": False, "points": p.tolist()}]))
    for turns in (1.5, 2, 3):
        for width in (0.3, 0.5):
            # The band between the spiral and itself moved outwards by a share of the pitch.
            p = spiral_points(turns, 0.3)
            pitch = (1.0 - 0.3) / turns
            th = np.linspace(0.0, 2 * math.pi * turns, len(p))
            dirs = np.stack([np.cos(th), np.sin(th)], axis=1)
            outer = p + width * pitch * dirs
            ring = np.vstack([p, outer[::-1]])
            out.append((f"proc-band:{turns}:{width}", "outline", [{"closed": True, "points": ring.tolist()}]))
    for teeth in (1, 2, 3):
        for slot in (0.01, 0.02, 0.04, 0.06):
            for depth in (0.4, 0.7):
                # A unit square whose top has `teeth` slots `slot` wide cut `depth` deep.
                pts = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]
                for t in range(teeth, 0, -1):
                    cx = t / (teeth + 1)
                    pts += [(cx + slot / 2, 1.0), (cx + slot / 2, 1.0 - depth), (cx - slot / 2, 1.0 - depth), (cx - slot / 2, 1.0)]
                pts.append((0.0, 1.0))
                out.append((f"proc-comb:{teeth}:{slot}:{depth}", "outline", [{"closed": True, "points": [list(p) for p in pts]}]))
    for gap in (0.01, 0.02, 0.04):
        for inner in (0.3, 0.6):
            th = np.linspace(0.0, 2 * math.pi, 256, endpoint=False)
            c = np.stack([np.cos(th), np.sin(th)], axis=1)
            out.append((f"proc-rings:{gap}:{inner}", "outline", [
                {"closed": True, "points": c.tolist()},
                {"closed": True, "points": ((1.0 - gap) * c).tolist()},
                {"closed": True, "points": (inner * c).tolist()},
            ]))
    return out


def normalized(pls):
    """Into [0.1, 0.9]^2, aspect kept (the simulator's shapes' box)."""
    pts = np.array([p for pl in pls for p in pl["points"]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    s = 0.8 / max(hi - lo)
    off = 0.5 - s * (lo + hi) / 2
    return [{"closed": pl["closed"], "points": [list(s * np.array(p) + off) for p in pl["points"]]} for pl in pls]


def sample(pls, n, sigma, outliers, rng, sampling="uniform"):
    """n points by arc length over the curves (a stroke's two ends among them, as a pen
    records them), uniform or with a density varying smoothly along them by a factor of
    NONUNIFORM (three swells over the whole length, at a random phase), Gaussian noise
    sigma per coordinate, and a share of them replaced by outliers uniform over the
    padded box."""
    segs = []
    for pl in pls:
        p = np.array(pl["points"])
        q = np.roll(p, -1, axis=0) if pl["closed"] else p[1:]
        p = p if pl["closed"] else p[:-1]
        segs.append((p, q))
    a = np.concatenate([s[0] for s in segs])
    b = np.concatenate([s[1] for s in segs])
    length = np.linalg.norm(b - a, axis=1)
    cum = np.cumsum(length)
    n_out = int(round(outliers * n))
    ends = [np.array(pl["points"][e]) for pl in pls if not pl["closed"] for e in (0, -1)]
    m = max(n - n_out - len(ends), 0)
    if sampling == "nonuniform":
        # Rejection from the uniform: the density exp(a sin(.)) spans e^(2a) = NONUNIFORM.
        a_, phase, s = 0.5 * math.log(NONUNIFORM), rng.random() * 2 * math.pi, np.zeros(0)
        while len(s) < m:
            c = rng.random(4 * m + 16) * cum[-1]
            w = np.exp(a_ * np.sin(2 * math.pi * 3 * c / cum[-1] + phase) - a_)
            s = np.concatenate([s, c[rng.random(len(c)) < w]])
        s = s[:m]
    else:
        s = rng.random(m) * cum[-1]
    k = np.searchsorted(cum, s, side="right").clip(0, len(a) - 1)
    t = (s - (cum[k] - length[k])) / np.maximum(length[k], 1e-300)
    pts = a[k] + (b[k] - a[k]) * t[:, None]
    if ends:
        pts = np.vstack([pts, np.array(ends)])
    pts = pts + rng.normal(0.0, sigma, pts.shape) if sigma > 0 else pts
    if n_out:
        pts = np.vstack([pts, rng.uniform(0.0, 1.0, (n_out, 2))])
    return pts[rng.permutation(len(pts))]


def make(args):
    os.makedirs(args.dir, exist_ok=True)
    pool = [s for s in shapes() if part_of(s[0]) == args.part]
    first = 0 if args.part == "dev" else TEST_SEEDS
    if args.grid:
        # Distinct shapes, each at every noise level and sampling, with and without
        # outliers: the variants of a shape differ only in what the grid varies (and
        # their draws). The part's procedural shapes (spirals, bands, combs, rings) come
        # first, as the fonts hold few narrow channels.
        order = np.random.default_rng(first).permutation(len(pool))
        order = sorted(order, key=lambda i: not pool[int(i)][0].startswith("proc-"))
        variants = [(s, o, m) for s in NOISES for o in (0.0, OUTLIERS) for m in SAMPLINGS]
        for i in range(min(args.cases, len(pool))):
            seed = first + i
            name, kind, pls = pool[int(order[i])]
            n = DENSITIES[int(np.random.default_rng(seed).integers(len(DENSITIES)))]
            for k, (sigma, out, sampling) in enumerate(variants):
                rng = np.random.default_rng([seed, k])
                write_case(args.dir, f"{seed:06d}-{k:02d}", name, kind, pls, n, sigma, out, rng, sampling)
        return
    for seed in range(first, first + args.cases):
        rng = np.random.default_rng(seed)
        name, kind, pls = pool[int(rng.integers(len(pool)))]
        sigma = NOISES[int(rng.integers(len(NOISES)))]
        n = DENSITIES[int(rng.integers(len(DENSITIES)))]
        out = OUTLIERS if rng.random() < 0.5 else 0.0
        sampling = SAMPLINGS[int(rng.integers(len(SAMPLINGS)))]
        write_case(args.dir, f"{seed:06d}", name, kind, pls, n, sigma, out, rng, sampling)


def write_case(dir, case, name, kind, pls, n, sigma, out, rng, sampling="uniform"):
    """One case's points (NDJSON frame), truth and description."""
    truth = normalized(pls)
    pts = sample(truth, n, sigma, out, rng, sampling)
    with open(os.path.join(dir, case + ".ndjson"), "w") as f:
        json.dump({"stream": "glyphs", "frame": 0, "points": pts.round(7).tolist()}, f)
        f.write("\n")
    with open(os.path.join(dir, case + ".truth.json"), "w") as f:
        json.dump({"polylines": truth}, f)
    with open(os.path.join(dir, case + ".case.json"), "w") as f:
        json.dump({"case": case, "shape": name, "kind": kind, "points": n, "sigma": sigma, "outliers": out, "sampling": sampling}, f)


# ---- scoring ----


def segments(pls):
    out = []
    for pl in pls:
        p = np.array(pl["points"], dtype=float).reshape(-1, 2)
        if len(p) < 2:
            continue
        q = np.roll(p, -1, axis=0) if pl["closed"] else p[1:]
        out.append((p if pl["closed"] else p[:-1], q))
    if not out:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out])


def densify(pls, step):
    """Points along the curves every `step` at most (for distances between curves)."""
    a, b = segments(pls)
    out = [np.zeros((0, 2))]
    for p, q in zip(a, b):
        k = max(1, int(math.ceil(np.linalg.norm(q - p) / step)))
        t = np.arange(k)[:, None] / k
        out.append(p + (q - p) * t)
    for pl in pls:
        if pl["points"] and not pl["closed"]:
            out.append(np.array(pl["points"][-1:], dtype=float))
    return np.concatenate(out)


def root(parent, i):
    """The root of `i` in the union-find forest `parent`, halving the path on the way."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


def components(pls, link):
    """Connected pieces of a drawing: curves within `link` of each other are one."""
    n = len(pls)
    parent = list(range(n))

    def find(i):
        return root(parent, i)

    # Points every half link along each curve: two curves within `link` have a pair
    # of them within 1.5 link.
    dense = [densify([pl], 0.5 * link) for pl in pls]
    trees = [cKDTree(d) for d in dense]
    for i in range(n):
        for j in range(i + 1, n):
            if find(i) != find(j) and trees[i].query(dense[j], distance_upper_bound=1.5 * link)[0].min() <= 1.5 * link:
                parent[find(i)] = find(j)
    return len({find(i) for i in range(n)})


def crossings(pls):
    """Proper crossings between segments of the curves (not at a shared vertex)."""
    a, b = segments(pls)
    if len(a) < 2:
        return 0
    owner = np.concatenate([np.full(len(pl["points"]) - (0 if pl["closed"] else 1), i) for i, pl in enumerate(pls) if len(pl["points"]) >= 2])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    cell = max(float(np.median(np.linalg.norm(b - a, axis=1))) * 4, 1e-9)
    grid = {}
    for s in range(len(a)):
        for gx in range(int(lo[s, 0] // cell), int(hi[s, 0] // cell) + 1):
            for gy in range(int(lo[s, 1] // cell), int(hi[s, 1] // cell) + 1):
                grid.setdefault((gx, gy), []).append(s)
    seen, count = set(), 0

    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    for ids in grid.values():
        for x in range(len(ids)):
            for y in range(x + 1, len(ids)):
                s, t = ids[x], ids[y]
                if (s, t) in seen:
                    continue
                seen.add((s, t))
                p, q, r, u = a[s], b[s], a[t], b[t]
                # Neighbouring segments share a vertex; so do the pieces at a junction.
                shared = min(np.linalg.norm(e - f) for e in (p, q) for f in (r, u))
                if shared <= 1e-12:
                    continue
                d1, d2, d3, d4 = orient(p, q, r), orient(p, q, u), orient(r, u, p), orient(r, u, q)
                if d1 * d2 < 0 and d3 * d4 < 0:
                    count += 1
    return count


def arms(truth_dense_tree, truth_dense, centre, radius):
    """How many curve arms of the truth leave a disc: its crossings of the circle."""
    k = 64
    ring = centre + radius * np.stack([np.cos(np.arange(k) * 2 * np.pi / k), np.sin(np.arange(k) * 2 * np.pi / k)], axis=1)
    d, _ = truth_dense_tree.query(ring)
    near = d <= radius * 0.25
    # Runs of ring points near the truth, cyclically.
    if near.all():
        return 1
    return int(np.sum(near & ~np.roll(near, 1)))


def chain(edges):
    """Edges (pairs of points) joined into polylines at their shared ends: chains between
    vertices of degree other than 2, and the cycles left, closed."""
    key = lambda p: (round(p[0], 12), round(p[1], 12))
    nbr = {}
    for a, b in edges:
        ka, kb = key(a), key(b)
        if ka == kb:
            continue
        nbr.setdefault(ka, []).append(kb)
        nbr.setdefault(kb, []).append(ka)
    used, out = set(), []

    def walk(start, nxt):
        pts, prev, cur = [start], start, nxt
        used.add(frozenset((start, nxt)))
        while True:
            pts.append(cur)
            if len(nbr[cur]) != 2 or cur == start:
                return pts
            step = [n for n in nbr[cur] if frozenset((cur, n)) not in used]
            if not step:
                return pts
            prev, cur = cur, step[0]
            used.add(frozenset((prev, cur)))

    for v, ns in nbr.items():
        if len(ns) != 2:
            for n in ns:
                if frozenset((v, n)) not in used:
                    out.append({"closed": False, "points": [list(p) for p in walk(v, n)]})
    for v, ns in nbr.items():
        for n in ns:
            if frozenset((v, n)) not in used:
                pts = walk(v, n)
                if pts[-1] == pts[0]:
                    out.append({"closed": True, "points": [list(p) for p in pts[:-1]]})
                else:
                    out.append({"closed": False, "points": [list(p) for p in pts]})
    return out


def edges(args):
    for path in sorted(glob.glob(os.path.join(args.dir, "*.case.json"))):
        case = path[: -len(".case.json")]
        if not os.path.exists(case + ".edges"):
            continue
        segs = []
        for line in open(case + ".edges"):
            x1, y1, x2, y2 = map(float, line.split())
            segs.append(((x1, y1), (x2, y2)))
        rec = json.loads(open(case + ".recon.ndjson").readline())
        ms = float(open(case + ".cgal-ms").read())
        with open(case + ".cgal.ndjson", "w") as f:
            json.dump({"frame": 0, "polylines": chain(segs), "stats": {"hmin": rec["stats"]["hmin"], "ms": {"total": ms}}}, f)
            f.write("\n")


def score_case(d, case, peer="recon"):
    c = json.load(open(os.path.join(d, case + ".case.json")))
    truth = json.load(open(os.path.join(d, case + ".truth.json")))["polylines"]
    frame = json.loads(open(os.path.join(d, case + ".ndjson")).readline())
    data = np.array(frame["points"])
    path = os.path.join(d, f"{case}.{peer}.ndjson")
    rec = json.loads(open(path).readline()) if os.path.exists(path) and os.path.getsize(path) else None
    row = dict(c)
    if rec is None or "polylines" not in rec:
        row.update(error=(rec or {}).get("error", "no record"))
        return row
    pls = rec["polylines"]
    hmin = rec["stats"]["hmin"]
    bound = 3 * c["sigma"] + 2 * hmin
    diag = math.sqrt(2) * 0.8
    tdense = densify(truth, hmin / 4)
    ttree = cKDTree(tdense)
    rdense = densify(pls, hmin / 4)
    if len(rdense):
        rtree = cKDTree(rdense)
        recon_to_truth = float(ttree.query(rdense)[0].max())
        truth_to_recon = float(rtree.query(tdense)[0].max())
        away = float(cKDTree(data).query(np.array([p for pl in pls for p in pl["points"]]))[0].max())
    else:
        recon_to_truth = truth_to_recon = away = None
    zero = sum(1 for pl in pls for p, q in zip(pl["points"], pl["points"][1:] + (pl["points"][:1] if pl["closed"] else [])) if p == q)
    # Stars: a point where six or more long curves (spokes over a fifth of the diagonal)
    # end, where the truth has fewer arms than ends by more than two (a Hershey
    # asterisk's spokes are real).
    opened = [pl for pl in pls if not pl["closed"] and len(pl["points"]) > 1]
    long_piece = [float(np.sum(np.linalg.norm(np.diff(np.array(pl["points"]), axis=0), axis=1))) >= 0.2 * diag for pl in opened]
    ends = np.array([pl["points"][e] for pl in opened for e in (0, -1)]).reshape(-1, 2)
    spoke = np.repeat(np.array(long_piece, dtype=bool), 2)
    star = 0
    if len(ends) >= 6:
        et = cKDTree(ends)
        for i, e in enumerate(ends):
            near = et.query_ball_point(e, 2 * bound)
            k = len(near)
            if k >= 6 and int(spoke[near].sum()) >= 6 and k > arms(ttree, tdense, e, 5 * bound) + 2:
                star = 1
                break
    # Truth strokes that touch share a point; 1e-3 of the box is touching at this scale.
    link_t = 1e-3
    comp_truth = components(truth, link_t)
    comp_recon = components(pls, max(bound, 1e-9)) if pls else 0
    right = comp_truth == comp_recon and (c["kind"] == "strokes" or all(pl["closed"] for pl in pls))
    # A vertex where ten or more segments meet (curves' ends and interiors alike).
    degree = {}
    for pl in pls:
        p = [tuple(q) for q in pl["points"]]
        for a_, b_ in zip(p, p[1:] + (p[:1] if pl["closed"] and len(p) > 2 else [])):
            if a_ != b_:
                degree[a_] = degree.get(a_, 0) + 1
                degree[b_] = degree.get(b_, 0) + 1
    # The truth's length farther than the bound from every curve, as a share of it.
    if len(rdense):
        missed = float(np.mean(rtree.query(tdense)[0] > bound))
    else:
        missed = 1.0
    closed_truth = sum(1 for pl in truth if pl["closed"])
    loops = c["kind"] == "outline" and len(pls) == closed_truth and all(pl["closed"] for pl in pls)
    row.update(
        empty=not pls,
        max_degree=max(degree.values(), default=0),
        missed=missed,
        right_loops=bool(loops),
        hmin=hmin,
        bound=bound,
        curves=len(pls),
        warnings=[str(w) for w in rec.get("warnings", [])],
        components=[comp_recon, comp_truth],
        right_components=bool(right),
        hausdorff=None if recon_to_truth is None else max(recon_to_truth, truth_to_recon),
        recon_to_truth=recon_to_truth,
        truth_to_recon=truth_to_recon,
        within=recon_to_truth is not None and max(recon_to_truth, truth_to_recon) <= bound,
        away=away,
        away_from_data=away is not None and away > 0.1 * diag,
        star=bool(star),
        zero_length=zero,
        crossings=crossings(pls),
        ms=rec["stats"]["ms"]["total"],
    )
    return row


def score(args):
    cases = []
    for path in sorted(glob.glob(os.path.join(args.dir, "*.case.json"))):
        case = os.path.basename(path)[: -len(".case.json")]
        if args.peer != "recon" and not os.path.exists(os.path.join(args.dir, f"{case}.{args.peer}.ndjson")):
            continue
        cases.append(case)
    with concurrent.futures.ProcessPoolExecutor() as pool:
        rows = list(pool.map(score_case, [args.dir] * len(cases), cases, [args.peer] * len(cases), chunksize=8))
    for row in rows:
        print(json.dumps(row))
    summary(rows)


def summary(rows):
    """The table's rows: by kind and outliers, over noise levels; then by noise level too."""
    print()
    header()
    for kind in ("outline", "strokes"):
        for out in (0.0, OUTLIERS):
            row(rows, kind, out, None)
    print()
    header(by_noise=True)
    for kind in ("outline", "strokes"):
        for out in (0.0, OUTLIERS):
            for sigma in NOISES:
                row(rows, kind, out, sigma)
    contract(rows)


def contract(rows):
    """The point-cloud contract's measures (issue 64), by kind, outliers and sampling:
    cases with no curve, stars (a vertex of degree ten or more), outlines with the right
    number of closed loops, the share of the strokes' length farther than the bound from
    every curve, and the median Hausdorff distance."""
    print()
    print("| shapes | outliers | sampling | cases | empty | stars | right loops | strokes missed | median Hausdorff |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for kind in ("outline", "strokes"):
        for out in (0.0, OUTLIERS):
            for sampling in SAMPLINGS + [None]:
                rs = [r for r in rows if r["kind"] == kind and r["outliers"] == out and (sampling is None or r.get("sampling", "uniform") == sampling)]
                if not rs:
                    continue
                ok = [r for r in rs if "error" not in r]
                hd = [r["hausdorff"] if r["hausdorff"] is not None else float("inf") for r in ok]
                loops = f"{100 * sum(r['right_loops'] for r in ok) / len(rs):.1f}%" if kind == "outline" else "-"
                missed = f"{100 * sum(r['missed'] for r in ok) / max(len(ok), 1):.2f}%" if kind == "strokes" else "-"
                print(
                    f"| {'font outlines' if kind == 'outline' else 'Hershey strokes'} | {'5%' if out else 'none'} | {sampling or 'all'} | {len(rs)} | "
                    f"{sum(r['empty'] for r in ok)} | {sum(r['max_degree'] >= 10 for r in ok)} | {loops} | {missed} | "
                    f"{np.median(hd) if hd else float('nan'):.4f} |"
                )


def header(by_noise=False):
    noise = " σ |" if by_noise else ""
    print(f"| shapes | outliers |{noise} cases | right components | Hausdorff within bound | curves away from data | stars | zero-length segments | crossings | errors |")
    print("|---|---:|" + ("---:|" if by_noise else "") + "---:|---:|---:|---:|---:|---:|---:|---:|")


def row(rows, kind, out, sigma):
    rs = [r for r in rows if r["kind"] == kind and r["outliers"] == out and (sigma is None or r["sigma"] == sigma)]
    if not rs:
        return
    ok = [r for r in rs if "error" not in r]
    pct = lambda k: f"{100 * sum(1 for r in ok if r[k]) / len(rs):.1f}%"
    noise = "" if sigma is None else f" {sigma:g} |"
    print(
        f"| {'font outlines' if kind == 'outline' else 'Hershey strokes'} | {'5%' if out else 'none'} |{noise} {len(rs)} | "
        f"{pct('right_components')} | {pct('within')} | {sum(1 for r in ok if r['away_from_data'])} | "
        f"{sum(1 for r in ok if r['star'])} | {sum(r['zero_length'] for r in ok)} | {sum(r['crossings'] for r in ok)} | {len(rs) - len(ok)} |"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make")
    m.add_argument("dir")
    m.add_argument("--part", choices=["dev", "test"], required=True)
    m.add_argument("--cases", type=int, default=100)
    m.add_argument("--grid", action="store_true", help="CASES distinct shapes, each at every noise level with and without outliers")
    s = sub.add_parser("score")
    s.add_argument("dir")
    s.add_argument("--peer", default="recon", help="cgal: score CGAL's records (from `edges`) instead of isoline's")
    e = sub.add_parser("edges")
    e.add_argument("dir")
    args = ap.parse_args()
    {"make": make, "score": score, "edges": edges}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
