#!/usr/bin/env python3
"""Draws a stream's curves in the world: each frame's returns and curves placed by the
frame's pose, with the sensor's path. Usage: world-map.py FRAMES.ndjson RECORDS.ndjson
OUT.svg (FRAMES: the input frames with beams; RECORDS: isoline's results, which carry
each frame's pose)."""
import json
import math
import sys

frames_path, records_path, out_path = sys.argv[1:4]
frames = {}
for line in open(frames_path):
    f = json.loads(line)
    frames[f["frame"]] = f
records = [json.loads(line) for line in open(records_path)]


def world(pose, p):
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return (pose[0] + c * p[0] - s * p[1], pose[1] + s * p[0] + c * p[1])


returns, curves, path = [], [], []
for k, r in enumerate(records):
    pose = r.get("pose")
    f = frames.get(r.get("frame"))
    if pose is None or f is None:
        continue
    path.append(pose[:2])
    if k % 8 == 0:
        a0, da = f["angle_min"], f["angle_increment"]
        for i, rng in enumerate(f["ranges"]):
            if rng is not None and i % 3 == 0:
                a = a0 + i * da
                returns.append(world(pose, (rng * math.cos(a), rng * math.sin(a))))
    if k % 10 == 0 or k == len(records) - 1:
        for pl in r.get("polylines", []):
            curves.append([world(pose, q) for q in pl["points"]])

xs = [p[0] for p in returns] + [p[0] for c in curves for p in c]
ys = [p[1] for p in returns] + [p[1] for c in curves for p in c]
x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
pad = 0.05 * max(x1 - x0, y1 - y0)
scale = 900 / (x1 - x0 + 2 * pad)
width, height = 900, (y1 - y0 + 2 * pad) * scale
# A strip below the map for the legend and the scale bar, so neither covers data.
footer = 90


def xy(p):
    return f"{(p[0] - x0 + pad) * scale:.1f},{(y1 + pad - p[1]) * scale:.1f}"


out = [
    f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height + footer:.0f}" '
    f'viewBox="0 0 {width:.0f} {height + footer:.0f}">',
    '<rect width="100%" height="100%" fill="white"/>',
]
for c in curves:
    out.append(f'<polyline points="{" ".join(xy(p) for p in c)}" fill="none" '
               'stroke="#2a9d8f" stroke-width="5" stroke-opacity="0.35"/>')
out.append('<path d="' + "".join(f"M{xy(p)}h0.1" for p in returns) + '" '
           'stroke="#1d3557" stroke-width="1.6" stroke-linecap="round"/>')
out.append(f'<polyline points="{" ".join(xy(p) for p in path)}" fill="none" '
           'stroke="#e76f51" stroke-width="3"/>')
out.append(f'<path d="M0 {height:.1f}H{width:.0f}" stroke="#ccc" stroke-width="1"/>')
legend = [
    ('<path d="M0 -4H16" stroke="#e76f51" stroke-width="3"/>', "the scanner's path (its poses)"),
    ('<path d="M0 -4H16" stroke="#2a9d8f" stroke-width="5" stroke-opacity="0.35"/>',
     "curves of every 10th scan, placed by its pose"),
    ('<circle cx="8" cy="-4" r="1.5" fill="#1d3557"/>', "returns of every 8th scan"),
]
for k, (swatch, label) in enumerate(legend):
    y = height + 26 + 22 * k
    out.append(f'<g transform="translate(18 {y:.0f})">{swatch}<text x="24" y="0" '
               f'font-family="sans-serif" font-size="14">{label}</text></g>')
# The round length nearest a fifth of the width.
target = (x1 - x0 + 2 * pad) / 5
mag = 10 ** math.floor(math.log10(target))
length = min((m * mag for m in (1, 2, 5, 10)), key=lambda v: abs(v - target))
bx1, by = width - 20, height + footer - 20
bx0 = bx1 - length * scale
out.append(f'<path fill="none" stroke="#222" stroke-width="2" '
           f'd="M{bx0:.1f} {by - 6:.1f}V{by:.1f}H{bx1:.1f}V{by - 6:.1f}"/>'
           f'<text x="{(bx0 + bx1) / 2:.1f}" y="{by - 10:.1f}" font-family="sans-serif" '
           f'font-size="14" text-anchor="middle">{length:g} m</text>')
out.append("</svg>")
open(out_path, "w").write("\n".join(out) + "\n")
