#!/usr/bin/env bash
# The whole test suite, what CI runs: installs the Kafka-compatible broker the Kafka
# test starts (scripts/kafka-broker.sh, into .tools/), then runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/kafka-broker.sh install
cargo test --workspace --locked
