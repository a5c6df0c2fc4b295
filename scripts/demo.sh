#!/usr/bin/env bash
# Installs the dependencies, builds zerocal, and runs the main jobs on the embedded defaults:
# the paper's Table II experiment (a simulated IRB1600: patterns I, II and the optimal plan),
# then one complete calibration on the simulated cell (zerocald --sim --once: the simulated
# controller over TCP and the simulated USB-1408FS, the PSD servo at every pose, the journal,
# the solve), printing the identified offsets next to the simulated truth; then the session's
# summary.txt and report.html (zerocal report).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)"
build/bin/zerocal experiment table2
echo
echo "=== zerocald --sim --once: a full calibration on the simulated cell ==="
build/bin/zerocald --sim --once --seed "${ZEROCAL_SEED:-1}" --config /dev/null \
  --data-dir build/sessions
session=$(ls -d build/sessions/*/ | sort | tail -n 1)
echo
echo "=== zerocal report ${session}: summary.txt and report.html (open it in a browser) ==="
build/bin/zerocal report "${session}"
