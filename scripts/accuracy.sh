#!/usr/bin/env bash
# Accuracy table of the README: every synth shape at three noise levels, reconstructed
# with the default parameters and compared with its truth by `isoline eval` (the spiral
# and the bays at their default gap, 0.05).
# Usage: scripts/accuracy.sh [OUT_DIR]   (prints a Markdown table)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=${1:-target/accuracy}
mkdir -p "$out"
echo "| shape | points | sigma | hmin | Hausdorff | mean distance | components (recon/truth) | iterations | vertices | ms |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
shapes="circle ellipse square star c two-circles annulus spiral bays strokes"; sigmas="0 0.002 0.005"; n=2000
[ "$quick" = 1 ] && shapes="circle annulus" && sigmas="0.005" && n=500
for shape in $shapes; do
  for sigma in $sigmas; do
    f="$out/$shape-$sigma"
    $bin synth "$shape" --points $n --noise "$sigma" --seed 7 -o "$f.ndjson" --truth "$f.truth.json"
    $bin reconstruct "$f.ndjson" -o "$f.recon.ndjson" --stats "$f.stats.json"
    $bin eval "$f.recon.ndjson" --truth "$f.truth.json" > "$f.eval.json"
    python3 - "$f" "$shape" "$n" "$sigma" <<'PY'
import json, sys
f, shape, n, sigma = sys.argv[1:]
e = json.load(open(f + ".eval.json"))
s = json.load(open(f + ".stats.json"))
# No curve at all has no distances: a dash.
g = lambda x: "-" if x is None else f"{x:.2e}"
print(f"| {shape} | {n} | {sigma} | {s['hmin']:.2e} | {g(e['hausdorff'])} | {g(e['mean_distance'])} | "
      f"{e['components_recon']}/{e['components_truth']} | {s['iterations']} | {s['vertices']} | {s['ms']['total']:.0f} |")
PY
  done
done
