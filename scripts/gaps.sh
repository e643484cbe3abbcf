#!/usr/bin/env bash
# The gap table of docs/benchmarks.md: the spiral and the bays with walls GAP apart,
# sampled so that GAP is 8 sample spacings, clean and at sigma = 0.5% of the unit box's
# diagonal, over forty seeds (SEEDS="..." names others); a run passes with one closed
# loop within 3 sigma + 2 hmin of the truth. Prints a Markdown row per shape, gap and
# sigma: the runs with one loop, those that pass, those that pass within half a spacing
# more (the bound at bends and corners no sample shows), the runs whose sampling leaves
# no stretch of the truth longer than the gap without a sample (by each sample's
# nearest truth vertex) and how many of them pass within half a spacing more, and the
# medians of the Hausdorff distance and of the bound.
# Usage: [SEEDS="1 2 3"] scripts/gaps.sh [OUT_DIR]
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=${1:-target/gaps}
mkdir -p "$out"
seeds=${SEEDS:-$(seq -s " " 1 40)}; cases="spiral:0.08 bays:0.08 spiral:0.06 bays:0.06"
[ "$quick" = 1 ] && seeds="7" && cases="bays:0.08"
echo "| shape | gap | points | sigma | one loop | passed | passed, ½ spacing more | no hole past the gap: passed, ½ spacing more | median Hausdorff | median bound |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for c in $cases; do
  shape=${c%:*}; gap=${c#*:}
  for sigma in 0 0.00707; do
    # 8 spacings across the gap: the truth's length over the spacing gap / 8.
    $bin synth "$shape" --gap "$gap" --points 100 -o "$out/len.ndjson" --truth "$out/len.truth.json"
    n=$(python3 -c "
import json, math
t = json.load(open('$out/len.truth.json'))
L = sum(sum(math.dist(a, b) for a, b in zip(p['points'], p['points'][1:] + p['points'][:1]))
        for p in t['polylines'])
print(round(8 * L / $gap))")
    for seed in $seeds; do
      f="$out/$shape-$gap-$sigma-$seed"
      $bin synth "$shape" --gap "$gap" --points "$n" --noise "$sigma" --seed "$seed" \
        -o "$f.ndjson" --truth "$f.truth.json"
      $bin reconstruct "$f.ndjson" -o "$f.recon.ndjson" --stats "$f.stats.json"
      $bin eval "$f.recon.ndjson" --truth "$f.truth.json" > "$f.eval.json"
    done
    python3 - "$out" "$shape" "$gap" "$sigma" "$n" $seeds <<'PY'
import json, math, statistics, sys
out, shape, gap, sigma, n, *seeds = sys.argv[1:]
spacing = float(gap) / 8


def largest_hole(f):
    """The longest stretch of the (closed) truth with no sample's nearest vertex on it."""
    truth = json.load(open(f + ".truth.json"))["polylines"][0]["points"]
    at, s = [], 0.0
    for i, p in enumerate(truth):
        at.append(s)
        s += math.dist(p, truth[(i + 1) % len(truth)])
    cell, grid = spacing, {}
    for i, p in enumerate(truth):
        grid.setdefault((int(p[0] // cell), int(p[1] // cell)), []).append(i)
    found = []
    for q in json.loads(open(f + ".ndjson").readline())["points"]:
        cx, cy, r = int(q[0] // cell), int(q[1] // cell), 1
        while True:
            near = [i for x in range(cx - r, cx + r + 1) for y in range(cy - r, cy + r + 1)
                    for i in grid.get((x, y), [])]
            if near:
                break
            r += 1
        found.append(at[min(near, key=lambda i: math.dist(q, truth[i]))])
    found.sort()
    return max([b - a for a, b in zip(found, found[1:])] + [found[0] + s - found[-1]])


h, b, ok, half, loop, covered, covered_ok = [], [], 0, 0, 0, 0, 0
for seed in seeds:
    f = f"{out}/{shape}-{gap}-{sigma}-{seed}"
    e, s = json.load(open(f + ".eval.json")), json.load(open(f + ".stats.json"))
    bound = 3 * float(sigma) + 2 * s["hmin"]
    d = e["hausdorff"] if e["hausdorff"] is not None else float("inf")
    # One closed loop: an open polyline round the data (its loop left to the strokes)
    # is not the truth's closed curve, whatever its distance.
    curves = [json.loads(l) for l in open(f + ".recon.ndjson")][0]["polylines"]
    right = len(curves) == e["components_truth"] and all(c["closed"] for c in curves)
    loop += right
    ok += right and d <= bound
    within = right and d <= bound + 0.5 * spacing
    half += within
    if largest_hole(f) <= float(gap):
        covered += 1
        covered_ok += within
    h.append(d); b.append(bound)
print(f"| {shape} | {gap} | {n} | {sigma} | {loop}/{len(seeds)} | {ok}/{len(seeds)} | "
      f"{half}/{len(seeds)} | {covered_ok}/{covered} | "
      f"{statistics.median(h):.2e} | {statistics.median(b):.2e} |")
PY
  done
done
