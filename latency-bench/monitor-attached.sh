#!/usr/bin/env bash
# The RT loop's response time with and without a monitor attached, in one run.
#
# Rounds of the main job in real time (`rig launch scenarios/acoustic-rig.toml`, each
# `--duration` seconds) alternate in ABBA order: A without a watcher, B with `rig monitor`
# subscribed to the rig's telemetry and a client polling it as the page does
# (`/api/state` 4 times and `/api/points` 20 times a second) plus a Prometheus scrape of
# `/metrics` every second. Each round's response p50/p99 come from its report.json (the
# service's own HdrHistogram); the table gives them per round, the medians per variant,
# and B ÷ A of the medians. The watcher runs on the cores of WATCH_CPUS (a taskset list;
# default: the plant's core 0, off the service's RT core 1 as docs/deployment.md asks of
# everything else on the box; WATCH_CPUS=all starts it anywhere, and the monitor then
# moves itself off the RT core when the service's telemetry names it). Needs the release
# binaries (`cargo build --release --workspace --bins`), curl, taskset and python3.
#
#   [WATCH_CPUS=0] latency-bench/monitor-attached.sh [ROUNDS_PER_VARIANT] [SECONDS] [OUT]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-4}
seconds=${2:-10}
out=${3:-target/monitor-attached}
rig_bin=target/release/rig
[ -x "$rig_bin" ] || { echo "$rig_bin is missing: cargo build --release --workspace --bins" >&2; exit 2; }
command -v curl >/dev/null || { echo "curl is needed" >&2; exit 2; }
rm -rf "$out"
mkdir -p "$out"
rig=acoustic-rig
watch_cpus=${WATCH_CPUS:-0}
pin() { if [ "$watch_cpus" = all ]; then "$@"; else taskset -c "$watch_cpus" "$@"; fi; }

poll() { # poll ADDR: the page's and a scraper's requests, until killed
    local addr=$1 i=0
    while true; do
        curl -s "http://$addr/api/points?rig=$rig" >/dev/null || true
        if (( i % 5 == 0 )); then curl -s "http://$addr/api/state" >/dev/null || true; fi
        if (( i % 20 == 0 )); then curl -s "http://$addr/metrics" >/dev/null || true; fi
        i=$((i + 1))
        sleep 0.05
    done
}

order=()
for ((r = 0; r < rounds; r++)); do
    if (( r % 2 == 0 )); then order+=(A B); else order+=(B A); fi
done
n=0
for v in "${order[@]}"; do
    folder="$out/round-$n-$v"
    mon_pid=""; poll_pid=""
    if [ "$v" = B ]; then
        pin "$rig_bin" monitor --rig "$rig" --listen 127.0.0.1:0 >"$out/monitor-$n.log" 2>&1 &
        mon_pid=$!
        for _ in $(seq 100); do
            addr=$(sed -n 's#.*listening on http://\([^/]*\)/.*#\1#p' "$out/monitor-$n.log")
            [ -n "$addr" ] && break
            sleep 0.1
        done
        [ -n "$addr" ] || { echo "rig monitor did not start: $(cat "$out/monitor-$n.log")" >&2; exit 1; }
        export -f poll; export rig
        pin bash -c "poll $addr" & poll_pid=$!
    fi
    "$rig_bin" launch scenarios/acoustic-rig.toml --duration "$seconds" --run-folder "$folder" >"$out/launch-$n.log" 2>&1 || true
    [ -n "$poll_pid" ] && kill "$poll_pid" 2>/dev/null && wait "$poll_pid" 2>/dev/null || true
    [ -n "$mon_pid" ] && kill "$mon_pid" 2>/dev/null && wait "$mon_pid" 2>/dev/null || true
    n=$((n + 1))
done

echo "watcher on cores: $watch_cpus"
python3 - "$out" <<'EOF'
import json, pathlib, statistics, sys
out = pathlib.Path(sys.argv[1])
rows = {"A": [], "B": []}
print("| round | monitor | response p50 µs | response p99 µs | lost | verdict |")
print("| --- | --- | --- | --- | --- | --- |")
for d in sorted(out.glob("round-*"), key=lambda p: int(p.name.split("-")[1])):
    v = d.name.split("-")[2]
    rep = json.loads((d / "report.json").read_text())
    r = rep["latency"]["response"]
    rows[v].append((r["p50"] / 1e3, r["p99"] / 1e3))
    print(f"| {d.name.split('-')[1]} | {'attached' if v == 'B' else 'none'} | {r['p50']/1e3:.1f} | "
          f"{r['p99']/1e3:.1f} | {rep['stats']['skipped']} | {'OK' if rep['verdict']['ok'] else 'FAILED'} |")
med = {v: (statistics.median(x[0] for x in rows[v]), statistics.median(x[1] for x in rows[v])) for v in rows}
print()
print(f"median p50: none {med['A'][0]:.1f} µs, attached {med['B'][0]:.1f} µs, ratio {med['B'][0]/med['A'][0]:.3f}")
print(f"median p99: none {med['A'][1]:.1f} µs, attached {med['B'][1]:.1f} µs, ratio {med['B'][1]/med['A'][1]:.3f}")
EOF
