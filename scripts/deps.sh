#!/usr/bin/env bash
# The Debian packages the full build needs beyond a Rust toolchain and a C compiler:
# OpenSSL's headers and pkg-config, for Kafka over TLS (the `kafka-tls` feature, which
# the test suite builds). Installs them with apt-get when missing; scripts/test.sh
# runs it. A default build (`cargo build`) needs none of them.
set -euo pipefail
if pkg-config --exists openssl 2> /dev/null; then
  exit 0
fi
sudo=""
if [[ $(id -u) -ne 0 ]]; then
  sudo="sudo"
fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libssl-dev pkg-config > /dev/null
pkg-config --exists openssl
echo "deps: installed libssl-dev and pkg-config" >&2
