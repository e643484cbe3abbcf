#!/usr/bin/env bash
# The Hokuyo log's heading (docs/benchmarks.md, "The sweep's timing"): each beam stream
# (*.ndjson.gz) in $ISOLINE_REAL registered with `isoline map --register` from 16
# starts (its first 0 to 15 scans left out: on this log the registration's outcome
# turns on small differences, so one run says little), read as taken at once and with
# its beams' timing ([scan] time_increment, $TIME_INCREMENT seconds, default 0.1 s /
# 1024: a Hokuyo URG-04LX). Each run's heading error on the second lap (scans 450 on,
# every tenth) by scripts/manhattan-heading.py, which needs no reference poses where the
# walls meet at right angles, and the map's static returns within 5 cm.
# Usage: ISOLINE_REAL=DIR scripts/heading-drift.sh     (QUICK=1: two starts)
set -euo pipefail
. "$(dirname "$0")/lib.sh"
need_recordings
dir=target/heading-drift
mkdir -p "$dir"
starts=$(seq 0 15)
[ "$quick" = 1 ] && starts="0 1"
printf '[scan]\ntime_increment = %s\n' "${TIME_INCREMENT:-9.765625e-5}" > "$dir/timed.toml"
: > "$dir/empty.toml"
echo "| recording | beams | starts | heading error on the second lap, median (mean) of its size | static returns within 5 cm, median |"
echo "|---|---|---:|---:|---:|"
for input in "$real"/*.ndjson.gz; do
  [ -e "$input" ] || continue
  base=$(basename "$input" .ndjson.gz)
  zcat "$input" > "$dir/$base.ndjson"
  for way in empty timed; do
    : > "$dir/$base-$way.tsv"
    for skip in $starts; do
      stem=$dir/$base-$way-$skip
      tail -n +$((skip + 1)) "$dir/$base.ndjson" > "$stem.ndjson"
      "$bin" map "$stem.ndjson" --register -c "$dir/$way.toml" -q -o "$stem.svg" \
        --stats "$stem.json" --trajectory "$stem.tum" 2> /dev/null
      heading=$(python3 scripts/manhattan-heading.py "$stem.ndjson" "$stem.tum" $((450 - skip)))
      printf '%s\t%s\n' "$heading" "$stem.json" >> "$dir/$base-$way.tsv"
    done
    python3 - "$base" "$way" "$dir/$base-$way.tsv" <<'PY'
import json, statistics, sys
base, way, path = sys.argv[1:]
rows = [l.split("\t") for l in open(path).read().splitlines()]
errors = [abs(float(h)) for h, _ in rows]
maps = [100 * json.load(open(s.strip()))["scores"]["static_within"] for _, s in rows]
beams = "taken at once" if way == "empty" else "timed"
print(f"| {base} | {beams} | {len(rows)} | {statistics.median(errors):.1f}° ({statistics.mean(errors):.1f}°) | {statistics.median(maps):.1f}% |")
PY
  done
done
