#!/usr/bin/env bash
# Paper section 4.1 reproduced: the ellipse of the synth shapes, centred at
# (0.5, 0.5) in the unit domain, 1,000 samples, clean and with noise sigma = 0.003,
# reconstructed by both schemes from the paper's enclosing circle. Writes
# docs/img/paper-4.1-{clean,noisy}.svg and prints a Markdown table.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=target/paper-4.1
# The drawings go to docs/img, except in a quick run.
img=docs/img; points=1000; schemes="semi-implicit explicit"
[ "$quick" = 1 ] && img=$out && points=300 && schemes="semi-implicit"
mkdir -p "$out" "$img"
echo "| data | scheme | iterations | vertices | solve ms | renormalize ms | total ms | Hausdorff | stop |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---|"
for kind in clean noisy; do
  sigma=0; [ $kind = noisy ] && sigma=0.003
  $bin synth ellipse --points $points --noise $sigma --seed 41 -o "$out/$kind.ndjson" --truth "$out/$kind.truth.json"
  for scheme in $schemes; do
    r="$out/$kind-$scheme"
    $bin reconstruct "$out/$kind.ndjson" -c config/paper-4.1.toml --scheme $scheme \
      -o "$r.ndjson" --stats "$r.stats.json"
    $bin eval "$r.ndjson" --truth "$out/$kind.truth.json" > "$r.eval.json"
    python3 - "$r" "$kind" "$scheme" <<'PY'
import json, sys
r, kind, scheme = sys.argv[1:]
s = json.load(open(r + ".stats.json")); e = json.load(open(r + ".eval.json"))
m = s["ms"]
print(f"| {kind} | {scheme} | {s['iterations']} | {s['vertices']} | {m['solve']:.0f} | "
      f"{m['renormalize']:.0f} | {m['total']:.0f} | {e['hausdorff']:.2e} | {s['stop']} |")
PY
  done
  $bin reconstruct "$out/$kind.ndjson" -c config/paper-4.1.toml -o "$img/paper-4.1-$kind.svg" --mesh
done
