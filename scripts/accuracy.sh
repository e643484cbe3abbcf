#!/usr/bin/env bash
# Accuracy table of the README: every synth shape at three noise levels, reconstructed
# with the default parameters and compared with its truth by `isoline eval`.
# Usage: scripts/accuracy.sh [OUT_DIR]   (prints a Markdown table)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=target/release/isoline
out=${1:-target/accuracy}
mkdir -p "$out"
echo "| shape | points | sigma | hmin | Hausdorff | mean distance | components (recon/truth) | iterations | vertices | ms |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for shape in circle ellipse square star c two-circles annulus; do
  n=2000
  for sigma in 0 0.002 0.005; do
    f="$out/$shape-$sigma"
    $bin synth "$shape" --points $n --noise "$sigma" --seed 7 -o "$f.ndjson" --truth "$f.truth.json"
    $bin reconstruct "$f.ndjson" -o "$f.recon.ndjson" --stats "$f.stats.json"
    $bin eval "$f.recon.ndjson" --truth "$f.truth.json" > "$f.eval.json"
    python3 - "$f" "$shape" "$n" "$sigma" <<'PY'
import json, sys
f, shape, n, sigma = sys.argv[1:]
e = json.load(open(f + ".eval.json"))
s = json.load(open(f + ".stats.json"))
print(f"| {shape} | {n} | {sigma} | {s['hmin']:.2e} | {e['hausdorff']:.2e} | {e['mean_distance']:.2e} | "
      f"{e['components_recon']}/{e['components_truth']} | {s['iterations']} | {s['vertices']} | {s['ms']['total']:.0f} |")
PY
  done
done
