#!/usr/bin/env bash
# The "Try it" demo of docs/kafka.md, end to end: a Kafka-compatible broker on loopback
# (scripts/kafka-broker.sh), topics "frames" and "records" of 4 partitions, two
# daemons in one consumer group (config/kafka.toml), eight simulated robots' scans
# published to "frames", and the records read back from "records": how many frames
# each daemon reconstructed, how many records each robot got, and one record.
# PORT (default 9092) is the broker's port; FRAMES the scans per robot (default 40).
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/kafka-demo
port=${PORT:-9092}
frames=${FRAMES:-40}; [ "$quick" = 1 ] && frames=5
robots=8
mkdir -p "$dir"
kafka_broker "$port"
scripts/kafka-broker.sh topic frames 4 "$port" > /dev/null
scripts/kafka-broker.sh topic records 4 "$port" > /dev/null

# Eight robots, one stream each: the message key (the stream) spreads them over the
# partitions, and the group gives each daemon some of the partitions.
robot_frames "$dir/robots.ndjson" "$robots" "$frames"
total=$((robots * frames))

# config/kafka.toml as shipped, on this broker's port, each daemon's metrics on a port of
# its own so that this script can read them.
ports=()
for d in 1 2; do
  mport=$((port + 200 + d))
  ports+=("$mport")
  sed -e "s/127\.0\.0\.1:9092/127.0.0.1:$port/" -e "s/127\.0\.0\.1:0/127.0.0.1:$mport/" \
    config/kafka.toml > "$dir/daemon$d.toml"
  $bin run -c "$dir/daemon$d.toml" 2> "$dir/daemon$d.log" &
  pids+=($!)
done
metric() { # PORT NAME: the sum of a counter's series
  curl -s "http://127.0.0.1:$1/metrics" | awk -v m="$2" '$1 ~ "^"m {s += $2} END {print s + 0}'
}
# Both daemons in the group, each holding some of the 4 partitions.
wait_for_partitions 4 "${ports[@]}"

$bin publish "$dir/robots.ndjson" --brokers "127.0.0.1:$port" --to frames --replay fast
for _ in $(seq 600); do
  made=0
  for m in "${ports[@]}"; do made=$((made + $(metric "$m" isoline_records_total))); done
  [ "$made" -ge "$total" ] && break
  sleep 0.1
done
for d in 1 2; do
  echo "daemon $d: $(metric "${ports[$((d - 1))]}" isoline_records_total) frames reconstructed"
done

# The read-back: every partition of "records", as any Kafka consumer would read it.
tansu=$(scripts/kafka-broker.sh path)
for part in 0 1 2 3; do
  "$tansu" cat consume records --broker "tcp://127.0.0.1:$port" --partition "$part" \
    --max-wait-time-ms 500 > "$dir/records-$part.json"
done
python3 - "$dir" "$total" <<'PY'
import collections, json, sys
folder, total = sys.argv[1], int(sys.argv[2])
records = []
for part in range(4):
    # The consumer prints a JSON array of {key, value} a fetch.
    text, at, decoder = open(f"{folder}/records-{part}.json").read(), 0, json.JSONDecoder()
    while text[at:].strip():
        batch, at = decoder.raw_decode(text, at + len(text[at:]) - len(text[at:].lstrip()))
        records += [m["value"] for m in batch]
by_robot = collections.Counter(r["stream"] for r in records)
print(f"records read back: {len(records)} of {total} frames")
for robot, n in sorted(by_robot.items()):
    print(f"  {robot}: {n} records")
first = min(records, key=lambda r: (r["stream"], r["frame"]))
pieces = first.get("polylines") or []
points = sum(len(p["points"]) for p in pieces)
print(f"  {first['stream']} frame {first['frame']}: {len(pieces)} polylines, {points} points")
sys.exit(0 if len(records) == total else 1)
PY
