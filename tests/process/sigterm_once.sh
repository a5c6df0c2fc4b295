#!/bin/bash
# SIGTERM to `zerocald --sim --once` in the middle of a session: the session is aborted (robot
# stopped after the move in progress), every pose recorded so far stays in the journal with no
# torn line, no result is written, and the daemon exits with 3 (stopped) quickly.
set -u
zerocald=$1
dir=$(mktemp -d /tmp/zerocal-sigterm-XXXXXX)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; cat "$dir/log" 2>/dev/null | tail -20; exit 1; }

"$zerocald" --sim --once --even-if-not-usable --seed 3 --config /dev/null --set backend.sim_pace=0.05 --data-dir "$dir/sessions" >"$dir/out" 2>"$dir/log" &
pid=$!
# Paced at 1/20 of real time, the session takes a few seconds of wall time: wait for its journal,
# then half a second, and it is surely mid-session.
for _ in $(seq 1 1000); do
  journal=$(ls "$dir"/sessions/*/journal.jsonl 2>/dev/null | head -1)
  [ -n "$journal" ] && break
  kill -0 $pid 2>/dev/null || fail "zerocald ended before its session began"
  sleep 0.01
done
sleep 0.5
[ -n "$journal" ] || fail "no journal appeared"
kill -TERM $pid
start=$(date +%s%N)
wait $pid
code=$?
elapsed_ms=$(( ($(date +%s%N) - start) / 1000000 ))
[ $code -eq 3 ] || fail "exit code $code, expected 3 (stopped)"
[ $elapsed_ms -lt 5000 ] || fail "took $elapsed_ms ms to stop"
grep -q "signal 15" "$dir/log" || fail "the log does not say which signal stopped it"
grep -q "aborted" "$dir/log" || fail "the log does not say the session was aborted"
lines=$(wc -l <"$journal")
[ "$lines" -lt 8 ] || fail "all $lines poses recorded: the signal did not stop the session"
# Every line complete and numbered 0, 1, 2, ... (a torn line would have no newline).
if [ "$lines" -gt 0 ]; then
  [ "$(tail -c 1 "$journal" | od -An -c | tr -d ' ')" = '\n' ] || fail "the journal ends in a torn line"
fi
for i in $(seq 0 $((lines - 1))); do
  sed -n "$((i + 1))p" "$journal" | grep -q "\"index\":$i[,}]" || fail "line $((i + 1)) is not pose $i"
done
[ ! -e "$(dirname "$journal")/result.json" ] || fail "a result was written for an aborted session"
echo "stopped in $elapsed_ms ms with $lines poses journalled"
