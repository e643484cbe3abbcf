#!/usr/bin/env bash
# The whole test suite, what CI runs: installs OpenSSL's headers for Kafka over TLS
# and Chromium for the HTML map's test (scripts/deps.sh) and the Kafka-compatible
# broker the Kafka tests start (scripts/kafka-broker.sh, into .tools/), checks the formatting, the lints (clippy,
# warnings denied) and the docs (rustdoc, warnings denied), runs every Rust test, then
# builds the Python package into a fresh virtual environment and runs its tests
# (scripts/python.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
# A clean build compiles the workspace's crates once: incremental compilation's
# bookkeeping only slows it (about 30 s of CI's 2-core build).
export CARGO_INCREMENTAL=0
scripts/deps.sh
# The Python environment, the Kafka tests' broker and the browser are installed
# (downloads, mostly) while cargo builds.
mkdir -p target
scripts/python.sh setup > target/python-setup.log 2>&1 &
setup=$!
# The benchmark scripts' own tools (scripts/tools.sh: CGAL's driver, the glyphs'
# Python) are not made: the scripts that need them measure by hand (the docs test
# skips them, and the real recordings' scripts end without the recordings).
(scripts/kafka-broker.sh install && scripts/deps.sh browser) > target/browser-setup.log 2>&1 &
browser=$!
# Style, lints and docs first: they fail in seconds to minutes, the tests take longer.
# The docs reuse the lints' check build of the dependencies (same features).
cargo fmt --all --check
cargo clippy --workspace --all-targets --features isoline/kafka-tls --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --features isoline/kafka-tls --locked
# Every crate in one invocation: the Python bindings have no Rust tests, but their
# dependencies' features are unified with the others', so that their build below
# reuses these crates (crates/py/Cargo.toml).
tests=(--workspace --exclude isoline-bench --features isoline/kafka-tls --locked)
cargo test "${tests[@]}" --no-run
# The tests need the broker and the browser.
if ! wait "$browser"; then
  cat target/browser-setup.log >&2
  exit 1
fi
# The integration tests (tests/it) are most of the tests' time, and spend part of it
# waiting (on the Kafka broker, child daemons, sockets and timeouts): they run beside
# the other tests and the Python package's, which fill those waits. Four test threads
# on CI's two cores overlap the waits within them (195 -> 159 s on two cores).
# The HTML map's test fails rather than skips without the browser.
ISOLINE_REQUIRE_BROWSER=1 cargo test "${tests[@]}" --test it -- --test-threads=4 \
  > target/it.log 2>&1 &
it=$!
# Every other test target, by the workspace's metadata: a test added is run. (The
# libraries and examples as `cargo test` picks them; the binary and the Python crate's
# library set `test = false`, and `--bins` would build their test harnesses.)
others=$(cargo metadata --format-version 1 --no-deps --locked | python3 -c '
import json, sys
m = json.load(sys.stdin)
print(" ".join(sorted({"--test " + t["name"] for p in m["packages"] if p["name"] != "isoline-bench"
                       for t in p["targets"] if "test" in t["kind"] and t["name"] != "it"})))')
status=0
# shellcheck disable=SC2086 # $others is a list of flags
cargo test "${tests[@]}" --lib --examples $others -- --test-threads=4 || status=1
cargo test "${tests[@]}" --doc || status=1
if ! wait "$setup"; then
  cat target/python-setup.log >&2
  status=1
else
  scripts/python.sh test || status=1
fi
wait "$it" || status=1
cat target/it.log
exit "$status"
