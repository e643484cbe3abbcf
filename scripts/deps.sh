#!/usr/bin/env bash
# The Debian packages beyond a Rust toolchain and a C compiler, installed with apt-get
# when missing; scripts/test.sh runs both.
#
#   scripts/deps.sh           # the full build's: OpenSSL's headers and pkg-config, for
#                             # Kafka over TLS (the `kafka-tls` feature the suite builds)
#   scripts/deps.sh browser   # Chromium, for the test that opens `isoline map`'s HTML
#                             # page in a headless browser (tests/it/map.rs)
#
# A default build (`cargo build`) needs none of them.
set -euo pipefail
what=${1:-build}
case $what in
  build) have() { pkg-config --exists openssl 2> /dev/null; }; packages=(libssl-dev pkg-config) ;;
  browser) have() { command -v chromium > /dev/null; }; packages=(chromium) ;;
  *) echo "usage: scripts/deps.sh [browser]" >&2; exit 2 ;;
esac
if have; then
  exit 0
fi
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  sudo="sudo"
fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${packages[@]}" > /dev/null
have
echo "deps: installed ${packages[*]}" >&2
