#!/usr/bin/env bash
# The strokes table of docs/benchmarks.md: the simulator's drawing of five open strokes
# (2,000 points) clean and at sigma = 0.002, 0.005 and 0.00707 (0.5% of the unit box's
# diagonal), over forty seeds (SEEDS="..." names others); a run has the right topology
# with 9 open polylines (the strokes, split where they meet) and junctions of 3, 3 and
# 4 polylines. Prints a Markdown row per sigma: the runs with the right topology, those
# of them whose every curve lies within 3 sigma + 2 hmin of the truth, those where also
# every truth point lies within that of a curve (passed), and the medians of both
# distances and of the bound.
# Usage: [SEEDS="1 2 3"] scripts/strokes.sh [OUT_DIR]
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=${1:-target/strokes}
mkdir -p "$out"
seeds=${SEEDS:-$(seq -s " " 1 40)}; sigmas="0 0.002 0.005 0.00707"
[ "$quick" = 1 ] && seeds="7" && sigmas="0.002"
echo "| sigma | right topology | curves within | passed | median curve to truth | median truth to curve | median bound |"
echo "|---:|---:|---:|---:|---:|---:|---:|"
for sigma in $sigmas; do
  for seed in $seeds; do
    f="$out/strokes-$sigma-$seed"
    $bin synth strokes --points 2000 --noise "$sigma" --seed "$seed" \
      -o "$f.ndjson" --truth "$f.truth.json"
    $bin reconstruct "$f.ndjson" -o "$f.recon.ndjson" --stats "$f.stats.json"
    $bin eval "$f.recon.ndjson" --truth "$f.truth.json" > "$f.eval.json"
  done
  python3 - "$out" "$sigma" $seeds <<'PY'
import json, statistics, sys
out, sigma, *seeds = sys.argv[1:]
right = within = passed = 0
ab, ba, bounds = [], [], []
for seed in seeds:
    f = f"{out}/strokes-{sigma}-{seed}"
    e, s = json.load(open(f + ".eval.json")), json.load(open(f + ".stats.json"))
    record = json.loads(open(f + ".recon.ndjson").readline())
    curves = record["polylines"]
    degrees = sorted(len(j["polylines"]) for j in record.get("junctions", []))
    topology = len(curves) == 9 and not any(c["closed"] for c in curves) and degrees == [3, 3, 4]
    bound = 3 * float(sigma) + 2 * s["hmin"]
    inf = float("inf")
    d1 = e["recon_to_truth"] if e["recon_to_truth"] is not None else inf
    d2 = e["truth_to_recon"] if e["truth_to_recon"] is not None else inf
    right += topology
    within += topology and d1 <= bound
    passed += topology and d1 <= bound and d2 <= bound
    ab.append(d1); ba.append(d2); bounds.append(bound)
n = len(seeds)
print(f"| {sigma} | {right}/{n} | {within}/{n} | {passed}/{n} | {statistics.median(ab):.2e} | "
      f"{statistics.median(ba):.2e} | {statistics.median(bounds):.2e} |")
PY
done
