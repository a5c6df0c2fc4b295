#!/usr/bin/env bash
# Installs the dependencies, builds the three programs it runs (not the tests: scripts/test.sh
# builds those), and shows a robot's life on the simulated cell, then the paper's experiment:
# 1. the cell daemon on the simulated cell (zerocald --sim: the simulated controller over TCP and
#    the simulated USB-1408FS, in-process), driven from the shop-floor client over the
#    authenticated control port: a reference taken at the robot's known-good zeros (zerocal start
#    --kind reference); the daemon stopped, joint 3's motor replaced (its zero moved by 0.4 deg),
#    the daemon started again; a check that names the joint; a restore that measures the change;
#    its online apply, verified by a check against the reference; the robot's history; the
#    restore's summary.txt and report.html (zerocal-lab report, the engineer's program).
# The paper's Table II experiment is a research command, not a technician's day: the demo ends
# by naming it (zerocal-lab experiment table2).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target zerocal zerocal-lab zerocald

demo=build/demo
rm -rf "${demo}/sessions"
mkdir -p "${demo}"
# The control port's token: owner-only, or zerocald refuses it.
(umask 077 && head -c 24 /dev/urandom | base64 > "${demo}/token")
export ZEROCAL_TOKEN_FILE="${demo}/token"
log="${demo}/zerocald.log"
daemon=""
port=""
trap '[ -z "${daemon}" ] || kill "${daemon}" 2>/dev/null || true' EXIT

# zerocald on the seed's simulated cell, with any extra --set given; sim_pace 0.1: ten times
# faster than a real cell (a minute of cell time in a few seconds); control.port and web.port 0:
# any free port, read back from the log.
start_daemon() {
  build/bin/zerocald --sim --seed "${ZEROCAL_SEED:-1}" --config /dev/null \
    --data-dir "${demo}/sessions" --set control.token_file="${ZEROCAL_TOKEN_FILE}" \
    --set control.port=0 --set web.port=0 --set backend.sim_pace=0.1 "$@" > "${log}" 2>&1 &
  daemon=$!
  port=""
  web=""
  for _ in $(seq 100); do
    port=$(sed -n 's/.*control port listening on 127\.0\.0\.1:\([0-9]*\).*/\1/p' "${log}")
    web=$(sed -n 's/.*web terminal listening on \(http:[^ ]*\).*/\1/p' "${log}")
    [ -n "${port}" ] && [ -n "${web}" ] && break
    kill -0 "${daemon}" 2>/dev/null || { cat "${log}"; exit 1; }
    sleep 0.1
  done
  [ -n "${port}" ] || { echo "zerocald did not open its port"; cat "${log}"; exit 1; }
  echo "zerocald (pid ${daemon}) serves 127.0.0.1:${port}; its log: ${log}"
  echo "the shop-floor terminal in a browser: ${web} (the token: ${ZEROCAL_TOKEN_FILE}; docs/web.md)"
}
stop_daemon() {
  kill -TERM "${daemon}"
  wait "${daemon}" || true
  daemon=""
}

echo
echo "=== zerocald --sim: the cell daemon on the simulated cell ==="
start_daemon
echo
echo "=== zerocal start --kind reference: the robot's zeros recorded while it is known good ==="
build/bin/zerocal start --port "${port}" --kind reference --watch
stop_daemon

echo
echo "=== months later: joint 3's motor replaced, its zero 0.4 deg off; the daemon started again ==="
start_daemon --set backend.sim_zero_change_joint=3 --set backend.sim_zero_change_deg=0.4
echo
echo "=== zerocal start --kind check: has a zero moved since the reference? (a few poses) ==="
build/bin/zerocal start --port "${port}" --kind check --watch || true
echo
echo "=== zerocal start --kind restore: the change of each zero since the reference ==="
build/bin/zerocal start --port "${port}" --kind restore --watch
echo
echo "=== zerocal apply --confirm: written online, verified by a check against the reference ==="
restore=$(ls "${demo}/sessions" | grep -v '\.' | sort | tail -n 1)
build/bin/zerocal apply --port "${port}" --confirm "${restore}"
echo
echo "=== zerocal history: the robot's record ==="
build/bin/zerocal history --port "${port}"
stop_daemon
trap - EXIT
session="${demo}/sessions/${restore}"
echo
echo "=== zerocal-lab report ${session}: summary.txt and report.html (open it in a browser) ==="
build/bin/zerocal-lab report "${session}"

echo
echo "=== the robot is back at its reference's zeros, verified ==="
echo "the paper's Table II experiment (patterns I, II and zerocal's optimal plan, Monte Carlo):"
echo "  build/bin/zerocal-lab experiment table2"
