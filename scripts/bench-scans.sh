#!/usr/bin/env bash
# The CPU-per-frame benches of docs/benchmarks.md (benches/benches/scans.rs), with the
# real frames: the ACES CARMEN log (SICK LMS, 180 beams) and the Mines Hokuyo stream
# (URG-04LX, 683 beams) from $ISOLINE_REAL are unpacked into target/bench-scans/ and
# named to the bench. Extra arguments go to criterion (e.g. a filter).
# Usage: ISOLINE_REAL=DIR scripts/bench-scans.sh [FILTER]
set -euo pipefail
cd "$(dirname "$0")/.."
real=${ISOLINE_REAL:-}
dir=target/bench-scans
mkdir -p "$dir"
if [ -f "$real/aces-corrected.log.gz" ]; then
  zcat "$real/aces-corrected.log.gz" > "$dir/aces.clf"
  export ISOLINE_BENCH_SICK=$PWD/$dir/aces.clf
fi
if [ -f "$real/mines-exp1-beams.ndjson.gz" ]; then
  zcat "$real/mines-exp1-beams.ndjson.gz" > "$dir/mines.ndjson"
  export ISOLINE_BENCH_HOKUYO=$PWD/$dir/mines.ndjson
fi
# The docs test runs every documented command quickly; a bench run is minutes of
# optimised build, which the test leaves to `cargo bench` as it does for every bench.
if [ "${QUICK:-0}" = 1 ]; then
  echo "QUICK=1: recordings unpacked; the bench itself runs under cargo bench" >&2
  exit 0
fi
cargo bench -p isoline-bench --bench scans -- "$@"
