#!/usr/bin/env bash
# The bash completion of zerocal, zerocal-lab, zerocald and zerocal-sim, with the programs of this
# build: commands, options and option values from --help, no duplicates, none of the old names
# that moved to zerocal-lab, nothing but options where options are completed; session ids from a
# running (simulated) daemon, and nothing, silently, when none answers.
# Usage: bash_completion_test.sh COMPLETION_FILE BIN_DIR
set -euo pipefail
bin=$(cd "$2" && pwd)
export PATH="${bin}:${PATH}"
# shellcheck source=/dev/null
source "$1"
fail() { echo "FAIL: $*" >&2; exit 1; }
work=$(mktemp -d)
# shellcheck source=tests/install/completion_test_lib.sh
source "$(dirname "$0")/completion_test_lib.sh"
trap 'stop_completion_daemon; rm -rf "${work}"' EXIT

complete -p zerocal zerocal-lab zerocald zerocal-sim | grep -c -- '-F _zerocal' | grep -qx 4 ||
  fail "complete -p: not every program is completed by _zerocal"

complete_words() {  # complete_words WORD... : the completions of the last word
  COMP_WORDS=("$@")
  COMP_CWORD=$(($# - 1))
  COMPREPLY=()
  _zerocal 2>"${work}/stderr"
  [ ! -s "${work}/stderr" ] || fail "'$*' wrote to stderr: $(cat "${work}/stderr")"
  [ "${#COMPREPLY[@]}" -eq 0 ] || printf '%s\n' "${COMPREPLY[@]}"
}
expect "zerocal-lab so" solve
expect "zerocal st" start status
expect "zerocal " start status watch abort resume continue sessions result verify acknowledge \
  robots history version plan apply
reject "zerocal " solve simulate report psd --robot  # moved to zerocal-lab, or not a command
expect "zerocal start --wa" --watch
expect "zerocal result --j" --json
expect "zerocal-lab experiment t" table2
expect "zerocald --on" --once
expect "zerocal-sim --po" --port
expect "zerocal start --pattern I" I II
expect "zerocal start --kind " calibrate reference check restore
expect "zerocald --kind r" reference restore
[ -z "$(complete_words zerocal start --pattern x)" ] || fail "--pattern x has completions"
[ -z "$(complete_words zerocal start --poses "")" ] || fail "--poses N has completions"
[ -z "$(complete_words zerocal start --host "")" ] || fail "--host ADDRESS has completions"
expect "zerocal start --watch --" --kind --json  # --watch and --json are flags: options follow
expect "zerocal result --json --" --host
expect "zerocal apply --" --confirm --json --host --port --token-file --timeout --help
reject "zerocal apply --" --moc --out --robot --unconfirmed-transmission  # zerocal-lab apply's
expect "zerocal-lab apply --" --moc --out
# Every option offered is an option of the command's --help, with nothing glued to it.
for words in "zerocal start --" "zerocald --" "zerocal-lab solve --" "zerocal-sim --"; do
  read -ra w <<<"${words}"
  help=$("${w[@]:0:${#w[@]}-1}" --help)
  while read -r option; do
    [[ ${option} =~ ^--[a-z0-9-]+$ ]] || fail "'${words}' offers ${option}"
    grep -qE -- "(^|[ ,])${option}( |$)" <<<"${help}" || fail "'${words}' offers ${option}, not in --help"
  done < <(complete_words "${w[@]}")
  expect "${words}" --help
done

# Session ids: from the daemon at --host/--port with --token-file, for the commands that take one.
[ -z "$(complete_words zerocal result --port 1 --token-file /nonexistent "")" ] ||
  fail "session ids offered with no daemon"
start_completion_daemon "${bin}" "${work}"
reach="--port ${ZEROCAL_TEST_PORT} --token-file ${ZEROCAL_TEST_TOKEN}"
for command in result resume apply verify acknowledge; do
  expect "zerocal ${command} ${reach} " "${ZEROCAL_TEST_SESSION}"
done
expect "zerocal start --kind check ${reach} --reference " "${ZEROCAL_TEST_SESSION}"
ZEROCAL_TOKEN_FILE=${ZEROCAL_TEST_TOKEN} expect "zerocal result --port ${ZEROCAL_TEST_PORT} 2" \
  "${ZEROCAL_TEST_SESSION}"
reject "zerocal result ${reach} ${ZEROCAL_TEST_SESSION} " "${ZEROCAL_TEST_SESSION}"  # one id only
reject "zerocal status ${reach} " "${ZEROCAL_TEST_SESSION}"
stop_completion_daemon
[ -z "$(complete_words zerocal result ${reach} "")" ] || fail "session ids offered after the daemon stopped"
echo "ok"
