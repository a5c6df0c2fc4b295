#!/usr/bin/env bash
# ctest's run of one libFuzzer target: SECONDS of fuzzing on a copy of its corpus (the tree's
# corpus is only read), failing on any crash, hang, leak or sanitizer report. What it finds is
# kept in FINDINGS (crash-*, timeout-*, ...): add such an input to the corpus as a regression
# input once the reader is fixed (docs/fuzzing.md).
set -euo pipefail
fuzzer=$1 corpus=$2 seconds=$3 findings=$4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r "$corpus"/. "$work"/
mkdir -p "$findings"
"$fuzzer" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
  -print_final_stats=1 -artifact_prefix="$findings/" "$work"
