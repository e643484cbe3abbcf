#!/usr/bin/env bash
# Fuzzes the seven targets of fuzz/ (cargo-fuzz, libFuzzer) with the nightly toolchain,
# two at a time: points and config for SECONDS_SMALL each, frame and reconstruct for
# SECONDS_BIG each, recording (bags and CARMEN logs), carmen (the CARMEN reader alone)
# and map (the world map's frames) for SECONDS_SMALL (defaults 360 and 600: 50 minutes
# of fuzzing in all). Each target
# starts from fuzz/seeds/TARGET; an input that crashes or hangs (10 s) is copied into
# fuzz/regressions/TARGET, which `cargo test --test it fuzz_regressions` replays on stable.
# Prints each target's executions and coverage and exits non-zero on any crash.
# QUICK=1 (the docs test, which must stay fast on stable) only checks that every
# target has its harness and seeds; `cargo test --test it fuzz_regressions` runs them.
# Usage: scripts/fuzz.sh [SECONDS_SMALL SECONDS_BIG]
set -euo pipefail
# The real checkout, also when run through a link to scripts/ (the docs test).
cd "$(dirname "$(readlink -f "$0")")/.."
small=${1:-360}
big=${2:-600}
targets="points config frame reconstruct recording carmen map"
if [ "${QUICK:-0}" = 1 ]; then
  for t in $targets; do
    if [ ! -f "fuzz/fuzz_targets/$t.rs" ] || [ -z "$(ls "fuzz/seeds/$t")" ]; then
      echo "fuzz target $t has no harness or no seeds" >&2
      exit 1
    fi
  done
  echo "QUICK=1: targets and seeds in place ($targets); not fuzzing"
  exit 0
fi
command -v cargo-fuzz > /dev/null || cargo install --locked cargo-fuzz
rustup toolchain list | grep -q nightly || rustup toolchain install nightly --profile minimal
cd fuzz
cargo +nightly fuzz build -O
status=0
run() { # target seconds max_len
  local t=$1
  mkdir -p "corpus/$t" "artifacts/$t" "regressions/$t"
  cp -n seeds/$t/* "corpus/$t/" 2> /dev/null || true
  if ! cargo +nightly fuzz run -O "$t" "corpus/$t" -- -max_total_time="$2" \
      -max_len="$3" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1 \
      > "artifacts/$t.log" 2>&1; then
    echo "$t: CRASH (see fuzz/artifacts/$t.log)"
    cp artifacts/$t/* "regressions/$t/" 2> /dev/null || true
    return 1
  fi
  local runs cov
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "artifacts/$t.log" | grep -o '[0-9]*$')
  cov=$(grep -o 'cov: [0-9]*' "artifacts/$t.log" | tail -1)
  echo "$t: $2 s, $runs executions, $cov, no crash"
}
run points "$small" 4096 & a=$!
run config "$small" 4096 & b=$!
wait $a || status=1
wait $b || status=1
run frame "$big" 65536 & a=$!
run reconstruct "$big" 1024 & b=$!
wait $a || status=1
wait $b || status=1
run recording "$small" 65536 & a=$!
run carmen "$small" 65536 & b=$!
wait $a || status=1
wait $b || status=1
run map "$small" 4100 || status=1
exit $status
