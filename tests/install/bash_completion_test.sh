#!/usr/bin/env bash
# The bash completion of zerocal, zerocal-lab, zerocald and zerocal-sim, with the programs of this build.
# Usage: bash_completion_test.sh COMPLETION_FILE BIN_DIR
set -euo pipefail
export PATH="$2:${PATH}"
# shellcheck source=/dev/null
source "$1"
fail() { echo "FAIL: $*" >&2; exit 1; }
complete_words() {  # complete_words WORD... : the completions of the last word
  COMP_WORDS=("$@")
  COMP_CWORD=$(($# - 1))
  COMPREPLY=()
  _zerocal
  printf '%s\n' "${COMPREPLY[@]}"
}
expect() {  # expect "WORDS" COMPLETION...
  local words=$1 got
  shift
  # shellcheck disable=SC2086
  got=$(complete_words ${words})
  for want in "$@"; do
    grep -qx -- "${want}" <<<"${got}" || fail "'${words}' completes to [${got//$'\n'/ }], not ${want}"
  done
}
expect "zerocal-lab so" solve
expect "zerocal st" start status
expect "zerocal start --wa" --watch
expect "zerocal result --j" --json
expect "zerocal-lab experiment t" table2
expect "zerocald --on" --once
expect "zerocal-sim --po" --port
[ -z "$(complete_words zerocal start --pattern x)" ] || fail "--pattern x has completions"
expect "zerocal start --pattern I" I II
echo "ok"
