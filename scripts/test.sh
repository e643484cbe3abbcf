#!/usr/bin/env bash
# The whole test suite, what CI runs: installs OpenSSL's headers for Kafka over TLS
# (scripts/deps.sh) and the Kafka-compatible broker the Kafka tests start
# (scripts/kafka-broker.sh, into .tools/), runs every Rust test, then builds
# the Python package into a fresh virtual environment and runs its tests
# (scripts/python.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
scripts/kafka-broker.sh install
# The Python bindings have no Rust tests: scripts/python.sh builds and tests them.
cargo test --workspace --exclude isoline-py --features isoline/kafka-tls --locked
scripts/python.sh
