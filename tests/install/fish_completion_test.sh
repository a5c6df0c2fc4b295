#!/usr/bin/env bash
# The fish completion of zerocal, zerocal-lab, zerocald and zerocal-sim, with the programs of this
# build, asked as fish itself asks (complete -C): commands, options and option values without
# duplicates or the names that moved to zerocal-lab, and session ids from a running (simulated)
# daemon, silently nothing when none answers. Each program's file is found by fish's own lookup
# by name in a vendor completions folder made as the package makes it (links to zerocal.fish).
# Usage: fish_completion_test.sh COMPLETION_FILE BIN_DIR
set -euo pipefail
file=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
bin=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }
command -v fish >/dev/null || fail "fish is not installed (scripts/install-deps.sh)"
work=$(mktemp -d)
# shellcheck source=tests/install/completion_test_lib.sh
source "$(dirname "$0")/completion_test_lib.sh"
trap 'stop_completion_daemon; rm -rf "${work}"' EXIT
mkdir -p "${work}/completions" "${work}/home"
for program in zerocal zerocal-lab zerocald zerocal-sim; do
  ln -s "${file}" "${work}/completions/${program}.fish"
done

complete_line() {  # complete_line LINE : the candidates fish offers (descriptions dropped)
  HOME="${work}/home" XDG_CONFIG_HOME="${work}/home" PATH="${bin}:${PATH}" fish --no-config -c \
    'set -p fish_complete_path $argv[1]; complete -C"$argv[2]"' "${work}/completions" "$1" \
    2>"${work}/stderr" | cut -f1
  [ ! -s "${work}/stderr" ] || fail "'$1' wrote to stderr: $(cat "${work}/stderr")"
}
complete_words() { complete_line "$*"; }  # the words as the line fish is asked to complete
expect "zerocal st" start status
reject="solve report psd --robot" expect "zerocal " start status sessions result apply plan
expect "zerocal start --kind " calibrate reference check restore
expect "zerocal start --pattern " optimal I II mixed file
[ -z "$(complete_line "zerocal start --poses ")" ] || fail "--poses N has completions"
reject="--moc --out --robot" expect "zerocal apply --" --confirm --json --token-file
reject="--once:" expect "zerocald --" --once --config --kind
expect "zerocal-lab " solve plan experiment report
expect "zerocal-lab experiment t" table2
expect "zerocal-sim --po" --port

[ -z "$(complete_line "zerocal result --port 1 --token-file /nonexistent ")" ] ||
  fail "session ids offered with no daemon"
start_completion_daemon "${bin}" "${work}"
reach="--port ${ZEROCAL_TEST_PORT} --token-file ${ZEROCAL_TEST_TOKEN}"
for command in result resume apply verify acknowledge; do
  expect "zerocal ${command} ${reach} " "${ZEROCAL_TEST_SESSION}"
done
expect "zerocal start ${reach} --reference " "${ZEROCAL_TEST_SESSION}"
reject="${ZEROCAL_TEST_SESSION}" expect "zerocal status ${reach} "
echo "ok"
