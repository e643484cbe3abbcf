#!/usr/bin/env bash
# KISS-ICP beside `isoline map --register` on the pose table's runs: each CARMEN log in
# $ISOLINE_REAL with its poses replaced by the same drifting odometry (seeds $SEEDS,
# default "1 2 3"), registered by KISS-ICP with the odometry's motion as each scan's
# prediction (scripts/kiss-icp.py), scored against the corrected poses by `isoline eval
# --reference`, and its map drawn and scored by `isoline map` on its poses. Installs the
# `kiss-icp` package into .tools/kiss (pip) when missing. Rows as scripts/registration.sh
# prints them; KISS-ICP closes no loops, so its rows stand beside `register-noloops`.
# Usage: ISOLINE_REAL=DIR scripts/kiss-peer.sh
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
need_kiss
dir=target/kiss-peer
mkdir -p "$dir"
seeds=${SEEDS:-1 2 3}
: > "$dir/rows.txt"
for input in "$real"/*.log.gz; do
  [ -e "$input" ] || continue
  base=$(basename "$input" .log.gz)
  "$bin" convert "$input" -o "$dir/$base.ndjson" 2> /dev/null
  for seed in $seeds; do
    name=$dir/$base-s$seed
    scripts/drift-odometry.py "$dir/$base.ndjson" "$name.ndjson" "$name.ref.tum" "$seed"
    start=$(date +%s.%N)
    "$kiss" scripts/kiss-icp.py "$name.ndjson" "$name-kiss.tum" "$name-kiss.ndjson" > /dev/null
    end=$(date +%s.%N)
    "$bin" eval "$name-kiss.tum" --reference "$name.ref.tum" > "$name-kiss.eval.json"
    "$bin" map "$name-kiss.ndjson" -q -o "$name-kiss.svg" --stats "$name-kiss.json" 2> /dev/null
    echo "$base $name $(wc -l < "$name.ndjson") $start $end" >> "$dir/rows.txt"
  done
done
python3 - "$dir/rows.txt" <<'PY'
import json, statistics, sys
rows = {}
for line in open(sys.argv[1]):
    base, stem, scans, t0, t1 = line.split()
    e = json.load(open(stem + "-kiss.eval.json")); s = json.load(open(stem + "-kiss.json"))
    rows.setdefault(base, []).append((e, s, 1e3 * (float(t1) - float(t0)) / int(scans)))
med = statistics.median
for base, runs in rows.items():
    g = lambda fn: med([fn(e, s, ms) for e, s, ms in runs])
    rpe = lambda k, f: g(lambda e, s, ms: e["rpe"][k][f])
    print(f"| {base} | KISS-ICP | {len(runs)} | {g(lambda e, s, ms: e['ate_m']):.3f} "
          f"| {rpe(0, 'translation_m'):.3f}, {rpe(0, 'heading_deg'):.2f} "
          f"| {rpe(1, 'translation_m'):.3f}, {rpe(1, 'heading_deg'):.2f} "
          f"| {100 * g(lambda e, s, ms: s['scores']['static_within']):.1f}% "
          f"| {100 * g(lambda e, s, ms: s['scores']['seen_through']):.2f}% | | {g(lambda e, s, ms: ms):.1f} wall |")
PY
