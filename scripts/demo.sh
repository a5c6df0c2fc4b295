#!/usr/bin/env bash
# Installs the dependencies, builds the three programs it runs (not the tests: scripts/test.sh
# builds those), and shows a technician's day on the simulated cell, then the paper's experiment:
# 1. the cell daemon on the simulated cell (zerocald --sim: the simulated controller over TCP and
#    the simulated USB-1408FS, in-process), a calibration started and watched from the shop-floor
#    client (zerocal start --watch) over the authenticated control port, ending with the verdict
#    and the offsets (next to the simulated truth), and the session's summary.txt and report.html
#    (zerocal-lab report, the engineer's program);
# 2. the paper's Table II experiment (zerocal-lab: a simulated IRB1600, patterns I, II and the
#    optimal plan).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target zerocal zerocal-lab zerocald

echo
echo "=== zerocald --sim: the cell daemon on the simulated cell ==="
demo=build/demo
mkdir -p "${demo}"
# The control port's token: owner-only, or zerocald refuses it.
(umask 077 && head -c 24 /dev/urandom | base64 > "${demo}/token")
export ZEROCAL_TOKEN_FILE="${demo}/token"
log="${demo}/zerocald.log"
# sim_pace 0.1: the simulated cell runs ten times faster than a real one (a minute of cell time
# in a few seconds); control.port 0: any free port, read back from the log.
build/bin/zerocald --sim --seed "${ZEROCAL_SEED:-1}" --config /dev/null \
  --data-dir "${demo}/sessions" --set control.token_file="${ZEROCAL_TOKEN_FILE}" \
  --set control.port=0 --set backend.sim_pace=0.1 > "${log}" 2>&1 &
daemon=$!
trap 'kill "${daemon}" 2>/dev/null || true' EXIT
port=""
for _ in $(seq 100); do
  port=$(sed -n 's/.*control port listening on 127\.0\.0\.1:\([0-9]*\).*/\1/p' "${log}")
  [ -n "${port}" ] && break
  kill -0 "${daemon}" 2>/dev/null || { cat "${log}"; exit 1; }
  sleep 0.1
done
[ -n "${port}" ] || { echo "zerocald did not open its port"; cat "${log}"; exit 1; }
echo "zerocald (pid ${daemon}) serves 127.0.0.1:${port}; its log: ${log}"

echo
echo "=== zerocal start --watch: a calibration from the shop-floor client ==="
build/bin/zerocal plan --port "${port}"
build/bin/zerocal start --port "${port}" --even-if-not-usable --watch
echo
build/bin/zerocal status --port "${port}"


kill -TERM "${daemon}"
wait "${daemon}" || true
trap - EXIT
session=$(ls -d "${demo}"/sessions/*/ | sort | tail -n 1)
echo
echo "=== zerocal-lab report ${session}: summary.txt and report.html (open it in a browser) ==="
build/bin/zerocal-lab report "${session}"

echo
echo "=== the paper's Table II: patterns I and II and zerocal's optimal plan, both costs ==="
echo "(each row: a plan and a cost over Monte Carlo repeats; the pairwise cost failing on the optimal"
echo " plan is the paper's estimator failing, not zerocal: the ML rows are zerocal's)"
build/bin/zerocal-lab experiment table2
