#!/usr/bin/env bash
# The gap table of docs/benchmarks.md: the spiral and the bays with walls GAP apart,
# sampled so that GAP is 8 sample spacings, clean and at sigma = 0.5% of the unit box's
# diagonal, over forty seeds (SEEDS="..." names others); a run passes with one closed
# loop within 3 sigma + 2 hmin of the truth. Prints a Markdown row per shape, gap and
# sigma: the runs with one loop, those that pass, and the medians of the Hausdorff
# distance and of the bound.
# Usage: [SEEDS="1 2 3"] scripts/gaps.sh [OUT_DIR]
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=${1:-target/gaps}
mkdir -p "$out"
seeds=${SEEDS:-$(seq -s " " 1 40)}; cases="spiral:0.08 bays:0.08 spiral:0.06 bays:0.06"
[ "$quick" = 1 ] && seeds="7" && cases="bays:0.08"
echo "| shape | gap | points | sigma | one loop | passed | median Hausdorff | median bound |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
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
import json, statistics, sys
out, shape, gap, sigma, n, *seeds = sys.argv[1:]
h, b, ok, loop = [], [], 0, 0
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
    h.append(d); b.append(bound)
print(f"| {shape} | {gap} | {n} | {sigma} | {loop}/{len(seeds)} | {ok}/{len(seeds)} | "
      f"{statistics.median(h):.2e} | {statistics.median(b):.2e} |")
PY
  done
done
