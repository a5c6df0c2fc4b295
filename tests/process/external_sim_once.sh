#!/bin/bash
# `zerocald --sim --once` with the controller in an external zerocal-sim process: zerocal-sim on an
# ephemeral port (printed on stdout), the daemon pointed at it by backend.sim_host/sim_port, the
# session runs to a result and the daemon exits 0. zerocal-sim is killed however this ends.
set -u
zerocald=$1
zerocal_sim=$2
seed=3
dir=$(mktemp -d /tmp/zerocal-extsim-XXXXXX)
sim_pid=
cleanup() {
  [ -n "$sim_pid" ] && kill "$sim_pid" 2>/dev/null && wait "$sim_pid" 2>/dev/null
  rm -rf "$dir"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; tail -20 "$dir/log" 2>/dev/null; exit 1; }

"$zerocal_sim" --port 0 --seed $seed --pace 0.01 >"$dir/sim.out" 2>"$dir/sim.err" &
sim_pid=$!
port=
for _ in $(seq 1 500); do
  port=$(sed -n 's/^zerocal-sim listening on .*:\([0-9]*\)$/\1/p' "$dir/sim.out")
  [ -n "$port" ] && break
  kill -0 $sim_pid 2>/dev/null || fail "zerocal-sim ended: $(cat "$dir/sim.err")"
  sleep 0.01
done
[ -n "$port" ] || fail "zerocal-sim printed no port"

"$zerocald" --sim --once --even-if-not-usable --seed $seed --config /dev/null --set backend.sim_host=127.0.0.1 \
  --set backend.sim_port="$port" --set servo.settle_s=0.02 --data-dir "$dir/sessions" \
  >"$dir/out" 2>"$dir/log"
code=$?
[ $code -eq 0 ] || fail "zerocald exit code $code, expected 0"
ls "$dir"/sessions/*/result.json >/dev/null 2>&1 || fail "no result.json written"

# A zerocal-sim of another world is refused, naming both, and nothing is written as a result.
"$zerocald" --sim --once --even-if-not-usable --seed $((seed + 1)) --config /dev/null --set backend.sim_host=127.0.0.1 \
  --set backend.sim_port="$port" --data-dir "$dir/other" >"$dir/out" 2>"$dir/log"
code=$?
[ $code -eq 3 ] || fail "exit code $code for a mismatched world, expected 3 (session faulted)"
grep -q "simulates world" "$dir/log" || fail "the log does not name the mismatched worlds"
echo "external zerocal-sim on port $port: session done; mismatched world refused (exit $code)"
