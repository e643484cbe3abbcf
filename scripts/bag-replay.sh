#!/usr/bin/env bash
# The robotics-format runs of docs/benchmarks.md: 300 scans of the room by the
# Hokuyo-like sensor (1,080 beams, 40 Hz) driving 0.1 m a frame, as NDJSON and as a ROS 2
# bag (LaserScan and Odometry, zstd chunks), through the daemon as fast as it takes
# them: NDJSON in, the bag in with its odometry, the bag in with an MCAP file out, and
# the bag in with the live view serving (no viewer connected). Each run three times;
# prints every summary line and the bag's size.
set -euo pipefail
. "$(dirname "$0")/lib.sh"
dir=target/bag-replay
n=300; [ "$quick" = 1 ] && n=10
mkdir -p "$dir"
$bin synth room --noise 0.01 --frames "$n" --motion 0.1 --seed 3 --stream laser \
  -o "$dir/room.ndjson"
$bin convert "$dir/room.ndjson" -o "$dir/room.mcap"
ls -l "$dir/room.ndjson" "$dir/room.mcap" | awk '{print "  " $5 " bytes " $9}'
for run in ndjson bag bag-mcap bag-live; do
  input=room.mcap; output=$run.ndjson; extra="odometry = \"/odom\""; live=""
  [ "$run" = ndjson ] && input=room.ndjson && extra=""
  [ "$run" = bag-mcap ] && output=$run.mcap
  [ "$run" = bag-live ] && live=$'[live]\nbind = "127.0.0.1:0"'
  cat > "$dir/$run.toml" <<TOML
[input]
path = "$input"
replay = "fast"
$extra
[output]
path = "$output"
$live
TOML
  echo "$run:"
  for k in 1 2 3; do
    $bin run -c "$dir/$run.toml" 2>&1 | grep "isoline run: [0-9]" | sed 's/^/  /'
  done
done
