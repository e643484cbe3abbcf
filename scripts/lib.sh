# Sourced by the scripts: the binary to run. ISOLINE_BIN names a built one (the docs
# test passes its own); otherwise the release build is made first. QUICK=1 asks each
# script for a small version of its run, which the docs test uses to check that every
# documented command works.
cd "$(dirname "$0")/.."
if [ -n "${ISOLINE_BIN:-}" ]; then
  bin=$ISOLINE_BIN
else
  cargo build --release --quiet
  bin=target/release/isoline
fi
quick=${QUICK:-0}
