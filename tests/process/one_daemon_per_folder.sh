#!/bin/bash
# Two zerocald on one data folder: the second stops at once, before it opens the cell, saying
# which process has the folder; once the first has stopped, a daemon starts there again.
set -u
zerocald=$1
dir=$(mktemp -d /tmp/zerocal-lock-XXXXXX)
first=
trap '[ -n "$first" ] && kill -9 $first 2>/dev/null; rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*"; tail -20 "$dir/first.log" 2>/dev/null; exit 1; }
(umask 077; echo "lock-test-token-0123456789" >"$dir/token")

"$zerocald" --sim --config /dev/null --data-dir "$dir/sessions" --set control.port=0 \
  --set web.port=0 --set control.token_file="$dir/token" >"$dir/first.log" 2>&1 &
first=$!
for _ in $(seq 1 500); do
  grep -q "listening" "$dir/first.log" && break
  kill -0 $first 2>/dev/null || fail "the first zerocald ended"
  sleep 0.02
done
grep -q "listening" "$dir/first.log" || fail "the first zerocald did not start serving"

"$zerocald" --sim --once --config /dev/null --data-dir "$dir/sessions" >"$dir/second.out" 2>&1
code=$?
[ $code -eq 1 ] || fail "the second zerocald exited $code, expected 1"
grep -q "another zerocald (pid $first) uses the data folder $dir/sessions" "$dir/second.out" ||
  fail "the second does not name the first: $(cat "$dir/second.out")"
grep -q "backend sim" "$dir/second.out" && fail "the second opened the cell before refusing"
[ -z "$(ls "$dir/sessions" | grep -v record.sqlite)" ] || fail "the second made a session"

kill -TERM $first
wait $first
first=
"$zerocald" --sim --once --even-if-not-usable --config /dev/null --data-dir "$dir/sessions" \
  >"$dir/third.out" 2>&1
code=$?
[ $code -eq 0 ] || fail "after the first stopped, a zerocald there exited $code: $(tail -3 "$dir/third.out")"
echo "the second was refused; after the first stopped the folder was free"
