#!/usr/bin/env bash
# The man pages in man/: each renders with groff without a warning and has the sections an
# administrator looks for; each names every subcommand and option its program's --help lists (so
# that neither can drift from the other): zerocal(1) every command of `zerocal help` (the moved
# ones too) and every option of each, zerocal-lab(1) every command and experiment, zerocald(8)
# and zerocal-sim(1) every option.
# Usage: man_pages_test.sh MAN_DIR BIN_DIR
set -euo pipefail
man=$(cd "$1" && pwd)
bin=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }
command -v groff >/dev/null || fail "groff is not installed (scripts/install-deps.sh)"

pages=(zerocal.1 zerocal-lab.1 zerocal-sim.1 zerocald.8)
for page in "${pages[@]}"; do
  warnings=$(LC_ALL=C.UTF-8 groff -man -Tutf8 -ww -z "${man}/${page}" 2>&1)
  [ -z "${warnings}" ] || fail "${page}: groff warns: ${warnings}"
  for section in NAME SYNOPSIS DESCRIPTION "EXIT STATUS" ENVIRONMENT FILES EXAMPLES "SEE ALSO"; do
    grep -qE "^\.SH \"?${section}\"?\$" "${man}/${page}" || fail "${page} has no ${section} section"
  done
done

# The page's text with roff's escaped hyphens as typed.
text() { sed 's/\\-/-/g' "${man}/$1"; }
# The subcommands that `$@` lists (the moved ones too) and the long options of `$@ --help`, except
# those listed under "Moved to zerocal-lab" (old names that only say where to go).
subcommands() { "$@" | awk '/^[A-Za-z]/ { s = ($0 ~ /^(Subcommands|Moved to)/) } s && /^  [a-z]/ { print $1 }'; }
options() {
  "$@" --help | awk '/^[A-Za-z]/ { moved = ($0 ~ /^Moved/) }
    !moved && /^  -/ { n = split($1, o, ","); for (i = 1; i <= n; ++i) if (o[i] ~ /^--/) print o[i] }' |
    grep -vx -- '--help'
}
has() {  # has PAGE WORD : WORD appears in PAGE as a word of its own
  grep -qE -- "(^|[^a-z0-9-])$2([^a-z0-9-]|\$)" <<<"$(text "$1")" || fail "$1 does not name $2"
}

count=0
commands=$(subcommands "${bin}/zerocal" help)
for command in ${commands}; do
  has zerocal.1 "${command}"
  count=$((count + 1))
  # Each command's options; moved commands have none to show.
  if "${bin}/zerocal" "${command}" --help >/dev/null 2>&1; then
    command_options=$(options "${bin}/zerocal" "${command}")
    for option in ${command_options}; do has zerocal.1 "${option}"; done
  fi
done
[ "${count}" -ge 15 ] || fail "zerocal help lists only ${count} commands"
commands=$(subcommands "${bin}/zerocal-lab" help)
for command in ${commands}; do has zerocal-lab.1 "${command}"; done
experiments=$(subcommands "${bin}/zerocal-lab" experiment --help)
[ -n "${experiments}" ] || fail "zerocal-lab experiment --help lists no experiment"
for experiment in ${experiments}; do
  has zerocal-lab.1 "${experiment}"
done
daemon_options=$(options "${bin}/zerocald")
for option in ${daemon_options}; do has zerocald.8 "${option}"; done
sim_options=$(options "${bin}/zerocal-sim")
for option in ${sim_options}; do has zerocal-sim.1 "${option}"; done
echo "${#pages[@]} pages render without warnings; zerocal(1) names ${count} commands and their options"
