#!/usr/bin/env bash
# The installed service, as `cmake --install` lays it out (into a scratch root, DESTDIR): the unit
# runs the installed zerocald with the installed configuration, the unit, udev rule and sysusers
# file are where systemd and udev read them, the board goes to group zerocal only, and systemd
# accepts the unit (`systemd-analyze verify`, no warning) and rates its sandbox 2.0 or better
# (`systemd-analyze security --offline`).
# Usage: installed_service_test.sh BUILD_DIR
set -euo pipefail
build=$1
root=$(mktemp -d)
trap 'rm -rf "${root}"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

DESTDIR=${root} cmake --install "${build}" >/dev/null

one() {  # the one installed file of this name, as its path on the target machine
  local found
  found=$(cd "${root}" && find . -name "$1" -type f | sed 's/^\.//')
  [ "$(printf '%s\n' "${found}" | grep -c .)" -eq 1 ] || fail "expected one $1, found: ${found:-none}"
  printf '%s\n' "${found}"
}
in_dirs() {  # is $1's folder one of the others?
  local dir=${1%/*}
  shift
  for d in "$@"; do [ "${dir}" = "${d}" ] && return 0; done
  return 1
}

unit=$(one zerocald.service)
in_dirs "${unit}" /etc/systemd/system /usr/lib/systemd/system /lib/systemd/system \
  /usr/local/lib/systemd/system || fail "${unit}: not a folder systemd reads system units from"
rule=$(one 60-zerocal-usb1408fs.rules)
in_dirs "${rule}" /etc/udev/rules.d /usr/lib/udev/rules.d /lib/udev/rules.d ||
  fail "${rule}: not a folder udev reads rules from"
sysusers=$(one zerocal.conf)
in_dirs "${sysusers}" /etc/sysusers.d /usr/lib/sysusers.d /usr/local/lib/sysusers.d ||
  fail "${sysusers}: not a folder systemd-sysusers reads"

# The unit names what was installed.
exec_start=$(sed -n 's/^ExecStart=//p' "${root}${unit}")
binary=${exec_start%% *}
[ -x "${root}${binary}" ] || fail "the unit runs ${binary}, which was not installed"
config=$(sed -n 's/.*--config \([^ ]*\).*/\1/p' <<<"${exec_start}")
config_dir=$(sed -n 's/.*--config-dir \([^ ]*\).*/\1/p' <<<"${exec_start}")
[ -f "${root}${config}" ] || fail "the unit reads ${config}, which was not installed"
[ -d "${root}${config_dir}" ] || fail "the unit reads drop-ins from ${config_dir}, not installed"
credential=$(sed -n 's/^LoadCredential=token://p' "${root}${unit}")
[ "${credential%/*}" = "${config%/*}" ] || fail "the token ${credential} is not beside ${config}"
grep -q '^User=zerocal$' "${root}${unit}" || fail "the unit does not run as zerocal"
grep -q '^u zerocal ' "${root}${sysusers}" || fail "${sysusers} does not make the user zerocal"

# The board: group zerocal and the seat's user, never every user.
grep -q 'GROUP="zerocal"' "${root}${rule}" || fail "${rule} does not give the board to zerocal"
! grep -q '0666' "${root}${rule}" || fail "${rule} opens the board to every user"

prefix=${binary%/bin/zerocald}
for f in bin/zerocal bin/zerocal-lab share/zerocal/rapid/ZerocalServer.mod \
  share/zerocal/web/index.html \
  share/bash-completion/completions/zerocal share/bash-completion/completions/zerocal-lab \
  share/bash-completion/completions/zerocald share/bash-completion/completions/zerocal-sim \
  share/man/man1/zerocal.1 share/man/man1/zerocal-lab.1 share/man/man8/zerocald.8 \
  share/man/man1/zerocal-sim.1 share/zsh/vendor-completions/_zerocal \
  share/fish/vendor_completions.d/zerocal.fish share/fish/vendor_completions.d/zerocal-lab.fish; do
  [ -f "${root}${prefix}/${f}" ] || fail "${prefix}/${f} was not installed"
done

if ! command -v systemd-analyze >/dev/null; then
  echo "systemd-analyze not found (scripts/install-deps.sh installs systemd): unit not verified"
  exit 0
fi
# systemd-analyze checks that ExecStart= exists on this machine: point it into the scratch root.
mkdir -p "${root}/check"
sed "s#^ExecStart=${binary}#ExecStart=${root}${binary}#" "${root}${unit}" \
  > "${root}/check/zerocald.service"
# It also opens the man pages of Documentation=: the installed ones.
verify=$(MANPATH="${root}${prefix}/share/man" systemd-analyze verify \
  "${root}/check/zerocald.service" 2>&1) ||
  fail "systemd-analyze verify: ${verify}"
[ -z "${verify}" ] || fail "systemd-analyze verify warns: ${verify}"
exposure=$(systemd-analyze security --offline=yes "${root}/check/zerocald.service" |
  sed -n 's/.*Overall exposure level for zerocald.service: \([0-9.]*\).*/\1/p')
[ -n "${exposure}" ] || fail "systemd-analyze security gave no exposure level"
awk -v e="${exposure}" 'BEGIN { exit !(e <= 2.0) }' ||
  fail "systemd-analyze security rates the unit ${exposure}, worse than 2.0"
echo "installed under ${prefix}: unit ${unit} verified, exposure ${exposure}"
