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

# The recordings in $ISOLINE_REAL (*.log.gz CARMEN logs, *.ndjson.gz beam streams, *.mcap
# ROS 2 bags) as
# $real; without them the script ends, successfully in a QUICK run (the docs test runs
# every documented command without the recordings).
need_recordings() {
  real=${ISOLINE_REAL:-}
  if [ -z "$real" ] || ! compgen -G "$real/*.gz" > /dev/null && ! compgen -G "$real/*.mcap" > /dev/null; then
    echo "no recordings in ISOLINE_REAL='$real' (*.log.gz CARMEN logs, *.ndjson.gz beam streams, *.mcap ROS 2 bags)" >&2
    [ "$quick" = 1 ] && exit 0
    exit 1
  fi
}

# The benchmarks' tools (CGAL's driver, the glyphs' Python, their fonts).
. scripts/tools.sh

# A Kafka-compatible broker on 127.0.0.1:$1 (scripts/kafka-broker.sh); at exit it stops,
# and so does every daemon whose pid the script put in $pids.
kafka_broker() {
  broker_port=$1
  scripts/kafka-broker.sh start "$broker_port"
  pids=()
  trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; scripts/kafka-broker.sh stop "$broker_port"' EXIT
}

# $2 simulated robots driving the room, $3 scans each, one stream a robot (robot0,
# robot1, ...), all in the NDJSON file $1 (each robot's also in $1's folder).
robot_frames() {
  local out=$1 robots=$2 frames=$3 i
  : > "$out"
  for i in $(seq 0 $((robots - 1))); do
    $bin synth room --frames "$frames" --motion 0.1 --seed $((i + 1)) --stream "robot$i" \
      -o "$(dirname "$out")/robot$i.ndjson"
    cat "$(dirname "$out")/robot$i.ndjson" >> "$out"
  done
}

# Waits (30 s at most) until the daemons whose metrics are on the ports after $1 hold
# all $1 partitions of their topic between them, each some.
wait_for_partitions() {
  local parts=$1 held each n m; shift
  for _ in $(seq 300); do
    held=0; each=1
    for m in "$@"; do
      n=$(curl -s "http://127.0.0.1:$m/metrics" | grep -c '^isoline_kafka_consumer_lag{' || true)
      held=$((held + n)); [ "$n" -gt 0 ] || each=0
    done
    [ "$held" = "$parts" ] && [ "$each" = 1 ] && return
    sleep 0.1
  done
}
