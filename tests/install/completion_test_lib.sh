# Sourced by the shell completion tests: what they check of each shell, and a simulated zerocald.
#
# The checks, on the test's own complete_words WORD... (what its shell offers for the last word)
# and fail MESSAGE; WORDS is a line of words, a trailing space in it an empty last word:
#   expect "WORDS" COMPLETION...  each COMPLETION is offered, none twice, none of ${reject:-}
#   reject "WORDS" COMPLETION...  none of these is offered
completions_of() {
  local -a w
  read -ra w <<<"$1"
  [[ $1 != *" " ]] || w+=("")
  complete_words "${w[@]}"
}
expect() {
  local words=$1 got
  shift
  got=$(completions_of "${words}")
  [ -z "$(sort <<<"${got}" | uniq -d)" ] || fail "'${words}' offers duplicates: $(sort <<<"${got}" | uniq -d)"
  for want in "$@"; do
    grep -qx -- "${want}" <<<"${got}" || fail "'${words}' completes to [${got//$'\n'/ }], not ${want}"
  done
  for bad in ${reject:-}; do
    ! grep -qx -- "${bad}" <<<"${got}" || fail "'${words}' offers ${bad}"
  done
}
reject() {
  local words=$1 got
  shift
  got=$(completions_of "${words}")
  for bad in "$@"; do
    ! grep -qx -- "${bad}" <<<"${got}" || fail "'${words}' offers ${bad}"
  done
}

# A simulated zerocald whose data folder holds one finished session, serving the control port on
# an ephemeral port. Sets ZEROCAL_TEST_PORT, _TOKEN and _SESSION; stop_completion_daemon ends it
# (call it from the test's EXIT trap).
# Usage: start_completion_daemon BIN_DIR WORK_DIR
start_completion_daemon() {
  local bin=$1 dir=$2 i
  (umask 077 && head -c 32 /dev/urandom | base64 > "${dir}/token")
  "${bin}/zerocald" --sim --once --even-if-not-usable --ideal-world --config /dev/null --seed 3 \
    --set session.poses=6 --data-dir "${dir}/data" >"${dir}/once.log" 2>&1 ||
    { cat "${dir}/once.log"; echo "FAIL: zerocald --sim --once made no session" >&2; exit 1; }
  ZEROCAL_TEST_SESSION=$(sed -n 's/.*calibration \([0-9]\{8\}T[0-9]\{6\}Z\)$/\1/p' "${dir}/once.log")
  [ -n "${ZEROCAL_TEST_SESSION}" ] || { echo "FAIL: no session id in the --once log" >&2; exit 1; }
  : >"${dir}/daemon.log"  # there before the background job opens it: the loop below reads it
  "${bin}/zerocald" --sim --config /dev/null --data-dir "${dir}/data" --set control.port=0 \
    --set control.token_file="${dir}/token" --set web.enabled=false >"${dir}/daemon.log" 2>&1 &
  zerocal_test_daemon_pid=$!
  ZEROCAL_TEST_TOKEN=${dir}/token
  ZEROCAL_TEST_PORT=
  for ((i = 0; i < 200; ++i)); do
    ZEROCAL_TEST_PORT=$(sed -n 's/.*control port listening on .*:\([0-9]*\)$/\1/p' "${dir}/daemon.log")
    [ -n "${ZEROCAL_TEST_PORT}" ] && return 0
    sleep 0.1
  done
  cat "${dir}/daemon.log"
  echo "FAIL: zerocald did not listen within 20 s" >&2
  exit 1
}

stop_completion_daemon() {
  [ -n "${zerocal_test_daemon_pid:-}" ] || return 0
  kill "${zerocal_test_daemon_pid}" 2>/dev/null || true
  wait "${zerocal_test_daemon_pid}" 2>/dev/null || true
  zerocal_test_daemon_pid=
}
