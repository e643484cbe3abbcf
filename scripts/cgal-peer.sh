#!/usr/bin/env bash
# isoline against CGAL's optimal-transport reconstruction (Optimal_transportation_
# reconstruction_2) on the simulator's shapes, side by side in one run: Hausdorff
# distance to the truth (`isoline eval` for both), components, vertices of degree other
# than 2, and milliseconds (the reconstruction alone for CGAL; isoline's total from its
# stats). Installs Debian's libcgal-dev if it is missing (apt-get, as root or through
# sudo) and builds the driver scripts/cgal/otr2.cpp into .tools/otr2.
# Usage: scripts/cgal-peer.sh [OUT_DIR] [TOLERANCE]   (prints a Markdown table)
# TOLERANCE is CGAL's Wasserstein tolerance, default 0.01 (1% of the unit box).
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=${1:-target/cgal-peer}
tol=${2:-0.01}
mkdir -p "$out"
need_otr2
score() { python3 scripts/cgal/score.py "$@"; }
echo "| shape | sigma | isoline Hausdorff | components | degree != 2 | ms | CGAL Hausdorff | components | degree != 2 | ms |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
shapes="circle square star c two-circles annulus spiral bays strokes"; sigmas="0 0.002 0.005"; n=2000
[ "$quick" = 1 ] && shapes="bays" && sigmas="0.002" && n=500
for shape in $shapes; do
  for sigma in $sigmas; do
    f="$out/$shape-$sigma"
    $bin synth "$shape" --points $n --noise "$sigma" --seed 7 -o "$f.ndjson" --truth "$f.truth.json"
    $bin reconstruct "$f.ndjson" -o "$f.isoline.ndjson" --stats "$f.stats.json"
    score xy "$f.ndjson" "$f.xy"
    "$otr" "$f.xy" "$tol" > "$f.edges" 2> "$f.cgal-ms"
    score segments "$f.edges" "$f.cgal.ndjson"
    for who in isoline cgal; do
      $bin eval "$f.$who.ndjson" --truth "$f.truth.json" > "$f.$who.eval.json"
      score graph "$f.$who.ndjson" > "$f.$who.graph.json"
    done
    python3 - "$f" "$shape" "$sigma" <<'PY'
import json, sys
f, shape, sigma = sys.argv[1:]
load = lambda name: json.load(open(f"{f}.{name}"))
h = lambda x: "-" if x is None else f"{x:.2e}"
row = [shape, sigma]
for who, ms in [("isoline", load("stats.json")["ms"]["total"]),
                ("cgal", float(open(f + ".cgal-ms").read()))]:
    e, g = load(f"{who}.eval.json"), load(f"{who}.graph.json")
    row += [h(e["hausdorff"]), str(g["components"]), str(g["degree_not_2"]), f"{ms:.0f}"]
print("| " + " | ".join(row) + " |")
PY
  done
done
