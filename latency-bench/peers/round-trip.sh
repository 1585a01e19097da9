#!/usr/bin/env bash
# The round trip per sample of each language path of the contract, in one sitting.
#
#   latency-bench/peers/round-trip.sh [STEPS] [ROUNDS]
#
# Every pairing runs STEPS samples (default 20000) of scenarios/first-order-lockstep.toml
# in lockstep with the static gain u = -2 y, ROUNDS times (default 5), the pairings
# interleaved round by round. The round trip is what the plant side measures: from
# publishing M_k to holding the answer to it (plant report `round_trip`, p50 and p99 in µs);
# for a plant in C or Python it is the same plant-side code (C) or its Python twin.
#
#   rust-rust     plant-proxy (Rust plant side)      against `service`
#   rust-python   plant-proxy                        against static_gain_controller.py
#   c-rust        first_order_plant.c (C interface)  against `service`
#   python-rust   first_order_plant.py (Python)      against `service`
#
# Needs: `cargo build --release --workspace` (the service, plant-proxy, libadaptive_rig),
# `cc`, and a Python with iceoryx2==0.10.0 and numpy in $RIG_PYTHON or target/py-venv
# (the tests make it). Prints one line per run and a table of the medians over the rounds.
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
STEPS=${1:-20000}
ROUNDS=${2:-5}
T=$ROOT/target/release
PY=${RIG_PYTHON:-$ROOT/target/py-venv/bin/python}
W=$(mktemp -d /tmp/peers-round-trip.XXXXXX)
export PYTHONPATH=$ROOT/ipc-types/python

for f in "$T/service" "$T/plant-proxy" "$PY"; do
    [ -x "$f" ] || { echo "missing $f (cargo build --release --workspace; the tests make target/py-venv)" >&2; exit 1; }
done
HAVE_C=0
if [ -f "$T/libadaptive_rig.a" ]; then
    cc -std=c11 -O2 -I ipc-types/include ipc-types/c/examples/first_order_plant.c \
        "$T/libadaptive_rig.a" -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc -o "$W/c_plant" && HAVE_C=1
fi

scenario() { # rig name -> scenario file
    { sed "s/^name = \"first-order-lockstep\"/name = \"$1\"/" scenarios/first-order-lockstep.toml
      cat tests/fixtures/service-tables.toml scenarios/lti/static-gain.toml; } > "$W/$1.toml"
    echo "$W/$1.toml"
}
field() { # json file, python expression on r -> value
    "$PY" -c "import json,sys; r=json.load(open(sys.argv[1])); print($2)" "$1"
}

run_pair() { # name, round
    local name=$1 i=$2 rig="rt-$1-$2" sc rep
    sc=$(scenario "$rig")
    rep="$W/$name-$i.json"
    case $name in
    rust-rust)
        "$T/service" run "$sc" --exit-with-plant --run-folder "$W/run-$name-$i" >/dev/null 2>&1 &
        "$T/plant-proxy" run "$sc" --mode lockstep --steps "$STEPS" --report "$rep" --quiet 2>/dev/null ;;
    rust-python)
        "$PY" ipc-types/python/examples/static_gain_controller.py --rig "$rig" >/dev/null 2>&1 &
        "$T/plant-proxy" run "$sc" --mode lockstep --steps "$STEPS" --report "$rep" --quiet 2>/dev/null ;;
    python-rust)
        "$T/service" run "$sc" --exit-with-plant --run-folder "$W/run-$name-$i" >/dev/null 2>&1 &
        "$PY" ipc-types/python/examples/first_order_plant.py --rig "$rig" --steps "$STEPS" --report "$rep" >/dev/null 2>&1 ;;
    c-rust)
        "$T/service" run "$sc" --exit-with-plant --run-folder "$W/run-$name-$i" >/dev/null 2>&1 &
        "$W/c_plant" "$rig" "$STEPS" lockstep --json 2>/dev/null | grep '^{' > "$rep" ;;
    esac
    wait
    printf '%-12s round %d: p50 %8.2f us  p99 %8.2f us  (%s samples)\n' "$name" "$i" \
        "$(field "$rep" "r['round_trip']['p50_us']")" "$(field "$rep" "r['round_trip']['p99_us']")" \
        "$(field "$rep" "r['round_trip']['samples']")"
    echo "$name $(field "$rep" "r['round_trip']['p50_us']") $(field "$rep" "r['round_trip']['p99_us']")" >> "$W/all.txt"
}

PAIRS="rust-rust rust-python python-rust"
if [ $HAVE_C = 1 ]; then PAIRS="$PAIRS c-rust"; else echo "no target/release/libadaptive_rig.a: the C path is left out" >&2; fi
for i in $(seq 1 "$ROUNDS"); do
    for p in $PAIRS; do run_pair "$p" "$i"; done
done
echo
echo "| path (plant -> controller) | round trip p50, µs (median of $ROUNDS) | p99, µs (median of $ROUNDS) |"
echo "| --- | --- | --- |"
for p in $PAIRS; do
    "$PY" - "$W/all.txt" "$p" <<'PYEOF'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1]) if l.split()[0] == sys.argv[2]]
p50 = statistics.median(float(r[1]) for r in rows)
p99 = statistics.median(float(r[2]) for r in rows)
print(f"| {sys.argv[2]} | {p50:.2f} | {p99:.2f} |")
PYEOF
done
echo "(runs in $W)"
