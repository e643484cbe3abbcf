#!/usr/bin/env bash
# The scale-out runs of docs/kafka.md: an in-memory Kafka-compatible broker on loopback
# (scripts/kafka-broker.sh), a 4-partition topic holding the scans of 8 simulated
# robots (the Hokuyo-like sensor, 1,080 beams, driving 0.1 m a frame through the room),
# and one, then two daemons in a consumer group reading it. Each run has topics of its
# own: the daemons join the group first, then every frame is published at once, and
# the run is timed from the publish to the last record; it prints frames/s and the
# daemons' CPU
# seconds per frame. PORT (default 19092) is the broker's port; FRAMES the scans per
# robot (default 100).
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/kafka-fleet
port=${PORT:-19092}
frames=${FRAMES:-100}; [ "$quick" = 1 ] && frames=3
robots=8
mkdir -p "$dir"
kafka_broker "$port"
robot_frames "$dir/fleet.ndjson" "$robots" "$frames"
total=$((robots * frames))

# GET http://127.0.0.1:$1/metrics
metrics() {
  curl -s "http://127.0.0.1:$1/metrics"
}
cpu_ticks() {  # user + system clock ticks of the daemons
  local s=0
  for p in "${pids[@]}"; do
    s=$((s + $(awk '{print $14 + $15}' "/proc/$p/stat")))
  done
  echo "$s"
}

runs=3; fleets="1 2"
# A quick run (the docs test) checks the script works: one daemon, one run.
[ "$quick" = 1 ] && runs=1 && fleets=1
for daemons in $fleets; do
  for k in $(seq "$runs"); do
    run="d$daemons-$k"
    scripts/kafka-broker.sh topic "frames-$run" 4 "$port" >/dev/null
    scripts/kafka-broker.sh topic "records-$run" 4 "$port" >/dev/null
    pids=(); ports=()
    for d in $(seq "$daemons"); do
      mport=$((port + 100 + d))
      ports+=("$mport")
      cat > "$dir/$run-$d.toml" <<TOML
[input]
kind = "kafka"
brokers = "127.0.0.1:$port"
topic = "frames-$run"
group = "fleet"
[input.kafka]
"session.timeout.ms" = 2000
"heartbeat.interval.ms" = 300
[output]
kind = "kafka"
brokers = "127.0.0.1:$port"
topic = "records-$run"
[metrics]
bind = "127.0.0.1:$mport"
TOML
      $bin run -c "$dir/$run-$d.toml" 2> "$dir/$run-$d.log" &
      pids+=($!)
    done
    wait_for_partitions 4 "${ports[@]}"
    cpu0=$(cpu_ticks)
    t0=$(date +%s.%N)
    $bin publish "$dir/fleet.ndjson" --brokers "127.0.0.1:$port" --to "frames-$run" \
      --replay fast 2>/dev/null
    while :; do
      done_=0
      for m in "${ports[@]}"; do
        n=$(metrics "$m" | awk '/^isoline_records_total/ {s += $2} END {print s + 0}')
        done_=$((done_ + n))
      done
      [ "$done_" -ge "$total" ] && break
      sleep 0.05
    done
    t1=$(date +%s.%N)
    cpu1=$(cpu_ticks)
    for p in "${pids[@]}"; do kill -TERM "$p"; wait "$p" || true; done
    pids=()
    awk -v n="$total" -v t0="$t0" -v t1="$t1" -v c="$((cpu1 - cpu0))" \
        -v hz="$(getconf CLK_TCK)" -v d="$daemons" \
      'BEGIN { printf "  %d daemon(s): %d frames in %.2f s: %.1f frames/s, %.1f ms CPU per frame\n",
               d, n, t1 - t0, n / (t1 - t0), 1000 * c / hz / n }'
  done
done
