#!/usr/bin/env bash
# Installs the dependencies, builds zerocal, and runs the main job on the embedded default:
# the paper's Table II experiment (a simulated IRB1600) with patterns I, II and the optimal plan.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)"
build/bin/zerocal experiment table2 "$@"
