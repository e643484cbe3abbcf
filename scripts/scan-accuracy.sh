#!/usr/bin/env bash
# The scan scores of docs/benchmarks.md: one scan of each simulated scene (room,
# corridor, clutter) by each sensor preset, range noise 1 cm, 2% dropout, seed 3,
# reconstructed with the defaults and scored by `isoline eval`; and the same frames
# through the split-and-merge baseline (scripts/split_and_merge.py). Prints a Markdown
# table; the bound is 3 sigma + 2 hmin.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
out=target/scan-accuracy
mkdir -p "$out"
scenes="room corridor clutter"
sensors="sick-tim sick-lms1xx hokuyo-utm30lx hokuyo-urg04lx rplidar-a1"
[ "$quick" = 1 ] && scenes="room" && sensors="sick-tim"
echo "| scene | sensor | returns | explained | free space | Hausdorff (bound) | openings bridged | walls missed | features | vertices | ms | split-and-merge: explained / Hausdorff |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for scene in $scenes; do
  for sensor in $sensors; do
    f="$out/$scene-$sensor"
    $bin synth "$scene" --sensor "$sensor" --noise 0.01 --dropout 0.02 --seed 3 \
      -o "$f.ndjson" --truth "$f.truth.json"
    $bin reconstruct "$f.ndjson" -o "$f.out.ndjson" --stats "$f.stats.json"
    $bin eval "$f.out.ndjson" --truth "$f.truth.json" --frames "$f.ndjson" > "$f.eval.json"
    python3 scripts/split_and_merge.py "$f.ndjson" "$f.sm.ndjson" 2> /dev/null
    $bin eval "$f.sm.ndjson" --truth "$f.truth.json" --frames "$f.ndjson" > "$f.sm.eval.json"
    python3 - "$f" "$scene" "$sensor" <<'PY'
import json, sys
f, scene, sensor = sys.argv[1:]
e = json.load(open(f + ".eval.json"))
s = json.load(open(f + ".stats.json"))
m = json.load(open(f + ".sm.eval.json"))
bound = 3 * 0.01 + 2 * s["hmin"]
print(f"| {scene} | {sensor} | {e['returns']} | {e['returns_explained']:.3f} | "
      f"{e['free_space_share']:.4f} | {e['hausdorff']:.3f} ({bound:.3f}) | "
      f"{e['openings_bridged']}/{e['openings']} | {e['walls_missed']} | {s['unexplained']} | "
      f"{s['vertices']} | {s['ms']['total']:.0f} | "
      f"{m['returns_explained']:.3f} / {m['hausdorff']:.3f} |")
PY
  done
done
