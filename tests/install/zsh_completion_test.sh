#!/usr/bin/env bash
# The zsh completion (_zerocal) of zerocal, zerocal-lab, zerocald and zerocal-sim, with the
# programs of this build: compinit binds it to the four programs; driven with zsh's words and
# CURRENT (compadd captured), it completes commands, options and option values without
# duplicates or the names that moved to zerocal-lab, and session ids from a running (simulated)
# daemon, silently nothing when none answers.
# Usage: zsh_completion_test.sh COMPLETION_DIR BIN_DIR
set -euo pipefail
dir=$(cd "$1" && pwd)
bin=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }
command -v zsh >/dev/null || fail "zsh is not installed (scripts/install-deps.sh)"
work=$(mktemp -d)
# shellcheck source=tests/install/completion_test_lib.sh
source "$(dirname "$0")/completion_test_lib.sh"
trap 'stop_completion_daemon; rm -rf "${work}"' EXIT

bound=$(zsh -f -c "fpath=('${dir}' \$fpath); autoload -Uz compinit; compinit -u -d '${work}/zcompdump'
  for c in zerocal zerocal-lab zerocald zerocal-sim; print -r -- \$c=\$_comps[\$c]")
[ "$(grep -c '=_zerocal$' <<<"${bound}")" -eq 4 ] || fail "compinit binds: ${bound}"

complete_words() {  # complete_words WORD... : what _zerocal offers for the last word
  PATH="${bin}:${PATH}" zsh -f -c '
    fpath=("$1" $fpath); shift; autoload -Uz _zerocal
    compadd() { while [[ $1 != -- ]]; do shift; done; shift; print -l -- "$@"; }
    _files() { print -- "<files $*>"; }
    words=("$@"); CURRENT=$#; _zerocal' zsh "${dir}" "$@" 2>"${work}/stderr" |
    { grep -v '^$' || true; }
  [ ! -s "${work}/stderr" ] || fail "'$*' wrote to stderr: $(cat "${work}/stderr")"
}
reject="solve report psd --robot" expect "zerocal " start status sessions result apply plan
expect "zerocal start --kind " calibrate reference check restore
expect "zerocal start --pattern " optimal I II mixed file
[ -z "$(complete_words zerocal start --poses "")" ] || fail "--poses N has completions"
reject="--moc --out --robot" expect "zerocal apply --" --confirm --json --token-file
expect "zerocald --" --once --config --config-dir --set --sim
reject="--once:" expect "zerocald --" --kind
expect "zerocal-lab " solve plan experiment report
expect "zerocal-lab experiment " table2 life
expect "zerocal-sim --" --port --world --seed
expect "zerocald --config " "<files >"
expect "zerocal-lab report " "<files -/>"

[ -z "$(complete_words zerocal result --port 1 --token-file /nonexistent "")" ] ||
  fail "session ids offered with no daemon"
start_completion_daemon "${bin}" "${work}"
reach="--port ${ZEROCAL_TEST_PORT} --token-file ${ZEROCAL_TEST_TOKEN}"
for command in result resume apply verify acknowledge; do
  expect "zerocal ${command} ${reach} " "${ZEROCAL_TEST_SESSION}"
done
expect "zerocal start ${reach} --reference " "${ZEROCAL_TEST_SESSION}"
reject="${ZEROCAL_TEST_SESSION}" expect "zerocal status ${reach} "
echo "ok"
