"""Glue for scripts/cgal-peer.sh.

  score.py xy FRAMES.ndjson OUT.xy            the first frame's points as `x y` lines
  score.py segments EDGES.txt OUT.ndjson      CGAL's edges as an isoline result record
  score.py graph RESULT.ndjson                components and vertices of degree other
                                              than 2 of a result's curves, as JSON
"""
import json
import sys
from collections import defaultdict


def xy(frames, out):
    with open(frames) as f:
        points = json.loads(f.readline())["points"]
    with open(out, "w") as o:
        o.writelines(f"{x!r} {y!r}\n" for x, y in points)


def segments(edges, out):
    polylines = []
    with open(edges) as f:
        for line in f:
            x1, y1, x2, y2 = map(float, line.split())
            polylines.append({"closed": False, "points": [[x1, y1], [x2, y2]]})
    with open(out, "w") as o:
        json.dump({"frame": 0, "polylines": polylines}, o)
        o.write("\n")


def graph(result):
    """Curves as a graph on their vertices (equal coordinates are one vertex)."""
    with open(result) as f:
        polylines = json.loads(f.readline())["polylines"]
    adj = defaultdict(set)
    for pl in polylines:
        pts = [tuple(p) for p in pl["points"]]
        n = len(pts)
        pairs = [(pts[i], pts[(i + 1) % n]) for i in range(n if pl["closed"] else n - 1)]
        for a, b in pairs:
            if a != b:
                adj[a].add(b)
                adj[b].add(a)
        for p in pts:
            adj.setdefault(p, set())
    seen, components = set(), 0
    for v in adj:
        if v in seen:
            continue
        components += 1
        stack = [v]
        seen.add(v)
        while stack:
            for w in adj[stack.pop()]:
                if w not in seen:
                    seen.add(w)
                    stack.append(w)
    odd = sum(1 for v in adj if len(adj[v]) != 2)
    print(json.dumps({"components": components, "degree_not_2": odd}))


if __name__ == "__main__":
    {"xy": xy, "segments": segments, "graph": graph}[sys.argv[1]](*sys.argv[2:])
