#!/usr/bin/env bash
# KISS-ICP beside `isoline map --register` on the pose table's runs: each CARMEN log in
# $ISOLINE_REAL with its poses replaced by the same drifting odometry (seeds $SEEDS,
# default "1 2 3"), registered by KISS-ICP with the odometry's motion as each scan's
# prediction (scripts/kiss-icp.py), scored against the corrected poses by `isoline eval
# --reference`, and its map drawn and scored by `isoline map` on its poses. Installs the
# `kiss-icp` package into .tools/kiss (pip) when missing. Rows as scripts/registration.sh
# prints them (scripts/pose-rows.py; the CPU column holds KISS-ICP's wall time a scan,
# Python's start included); KISS-ICP closes no loops, so its rows stand beside `register-noloops`.
# Usage: ISOLINE_REAL=DIR scripts/kiss-peer.sh
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
need_kiss
dir=target/kiss-peer
mkdir -p "$dir"
seeds=${SEEDS:-1 2 3}
: > "$dir/rows.tsv"
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
    ms=$(python3 -c "print(1e3 * ($end - $start) / $(wc -l < "$name.ndjson"))")
    printf '%s\tKISS-ICP\t%s\t%s\t%s\n' "$base" "$name-kiss.eval.json" "$name-kiss.json" "$ms" >> "$dir/rows.tsv"
  done
done
python3 scripts/pose-rows.py "$dir/rows.tsv"
