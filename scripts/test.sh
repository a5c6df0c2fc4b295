#!/usr/bin/env bash
# Installs the dependencies, builds everything and runs the whole test suite; then builds the
# readers' fuzz targets with clang and libFuzzer (build-fuzz: those targets and the libraries
# they need, nothing else) and fuzzes each for ZEROCAL_FUZZ_SECONDS (default 15) on a copy of
# its corpus (docs/development.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)"
ctest --test-dir build --output-on-failure --parallel "$(nproc)" --timeout 600

cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DZEROCAL_FUZZ=ON -DZEROCAL_BUILD_TESTS=OFF -DZEROCAL_BUILD_BENCHMARKS=OFF \
  -DZEROCAL_FUZZ_SECONDS="${ZEROCAL_FUZZ_SECONDS:-15}"
cmake --build build-fuzz --target zerocal_fuzzers --parallel "$(nproc)"
ctest --test-dir build-fuzz --output-on-failure --parallel "$(nproc)"
