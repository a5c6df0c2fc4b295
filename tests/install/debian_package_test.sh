#!/usr/bin/env bash
# The Debian package (debian/), made as an administrator would make it: the source package
# (dpkg-source -b) and the binary one (dpkg-buildpackage -b, with Debian's hardening flags, nocheck:
# the project's tests are this suite, and noautodbgsym: the debug symbols' package takes minutes to
# compress and holds nothing to check) from a copy of the source tree. Then lintian on both,
# with no error and no warning; what the package holds (the unit's zerocald, the configuration as
# conffiles, the udev rule, sysusers file, RAPID module, compressed man pages, the docs, the bash,
# zsh and fish completions), what it depends on (no particular BLAS), the binaries hardened
# (hardening-check: PIE, stack protector, FORTIFY, RELRO, BIND_NOW); and, when run as root, a
# real install into a scratch dpkg root (dpkg --root, maintainer scripts run with DPKG_ROOT
# there): the user and group made, the token made root:zerocal 0640, a technician's edit of a
# conffile kept over a reinstall, remove keeping the configuration, purge removing it and the
# token. ZEROCAL_PACKAGE_KEEP=DIR keeps the package files there.
# Usage: debian_package_test.sh SOURCE_DIR
set -euo pipefail
src=$(cd "$1" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }
for tool in dpkg-buildpackage dpkg-source dh dh_bash-completion lintian hardening-check; do
  command -v "${tool}" >/dev/null ||
    { echo "SKIP: ${tool} is not installed (scripts/install-deps.sh installs it)"; exit 77; }
done
work=$(mktemp -d)
trap 'rm -rf "${work}"' EXIT

version=$(dpkg-parsechangelog -l "${src}/debian/changelog" -S Version)
tree=${work}/zerocal-${version}
mkdir "${tree}"
# The copy: what git tracks or would track (no build folders), else the tree without them.
if git -C "${src}" rev-parse --show-toplevel >/dev/null 2>&1; then
  (cd "${src}" && git ls-files -z --cached --others --exclude-standard |
    tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -C "${tree}" -xf -
else
  (cd "${src}" && tar --exclude=./.git --exclude='./build' --exclude='./build-*' \
    --exclude='./obj-*' --exclude=./debian/.debhelper -cf - .) | tar -C "${tree}" -xf -
fi
[ -f "${tree}/debian/rules" ] || fail "the copy of ${src} has no debian/rules"

start=$(date +%s)
(cd "${work}" && dpkg-source -b "zerocal-${version}" >"${work}/source.log" 2>&1) ||
  { cat "${work}/source.log"; fail "dpkg-source -b failed"; }
(cd "${tree}" && DEB_BUILD_OPTIONS="nocheck noautodbgsym parallel=2" dpkg-buildpackage -us -uc -b \
  >"${work}/build.log" 2>&1) || { tail -50 "${work}/build.log"; fail "dpkg-buildpackage -b failed"; }
echo "source and binary packages built in $(($(date +%s) - start)) s"
deb=$(ls "${work}"/zerocal_"${version}"_*.deb)
[ -z "${ZEROCAL_PACKAGE_KEEP:-}" ] || cp "${work}"/zerocal_"${version}"* "${ZEROCAL_PACKAGE_KEEP}"

# lintian: no error, no warning, on the binary package (its .changes) and the source package.
lintian_out=$(lintian "${work}"/zerocal_"${version}"_*.changes "${work}/zerocal_${version}.dsc" 2>&1) ||
  true
! grep -E '^(E|W):' <<<"${lintian_out}" || fail "lintian: errors or warnings (above)"
grep -qE '^(internal error|.*[Ff]atal)' <<<"${lintian_out}" && fail "lintian failed: ${lintian_out}"

dpkg-deb -c "${deb}" | awk '{ print $6 }' | sed 's#^\./#/#; s#/$##' > "${work}/contents"
has() { grep -qx "$1" "${work}/contents" || fail "the package lacks $1"; }
dpkg-deb -e "${deb}" "${work}/control"
dpkg-deb -x "${deb}" "${work}/files"
unit=$(grep '/zerocald.service$' "${work}/contents") || fail "the package has no zerocald.service"
binary=$(sed -n 's/^ExecStart=\([^ ]*\).*/\1/p' "${work}/files${unit}")
config=$(sed -n 's/^ExecStart=.*--config \([^ ]*\).*/\1/p' "${work}/files${unit}")
prefix=${binary%/bin/zerocald}
confdir=${config%/*}
[ "${prefix}" = /usr ] && [ "${confdir}" = /etc/zerocal ] || fail "the unit runs ${binary} ${config}"
has "${binary}"
for program in zerocal zerocal-lab zerocal-sim; do has "/usr/bin/${program}"; done
has "${config}"
has "${confdir}/zerocald.d"
has "${confdir}/robots/irb1600-10-145.yaml"
has /usr/share/zerocal/rapid/ZerocalServer.mod
has /usr/share/zerocal/web/index.html  # the web terminal, where web.root finds it
has /lib/udev/rules.d/60-zerocal-usb1408fs.rules
has /usr/lib/sysusers.d/zerocal.conf
for page in man1/zerocal.1 man1/zerocal-lab.1 man1/zerocal-sim.1 man8/zerocald.8; do
  has "/usr/share/man/${page}.gz"
done
for program in zerocal zerocal-lab zerocald zerocal-sim; do
  has "/usr/share/bash-completion/completions/${program}"
  has "/usr/share/fish/vendor_completions.d/${program}.fish"
done
has /usr/share/zsh/vendor-completions/_zerocal
has /usr/share/doc/zerocal/copyright
has /usr/share/doc/zerocal/changelog.gz
for doc in README.md daemon.md cli.md protocol.md configuration.md; do
  has "/usr/share/doc/zerocal/${doc}"  # as the man pages cite it, uncompressed
done
! grep -q "${confdir}/token" "${work}/contents" || fail "the package ships a token"

# Every file under /etc is a conffile, and the conffiles exist.
find "${work}/files/etc" -type f | sed "s#^${work}/files##" | while read -r f; do
  grep -qx "${f}" "${work}/control/conffiles" || fail "${f} is not a conffile"
done
while read -r f; do has "${f}"; done < "${work}/control/conffiles"
depends=$(dpkg-deb -f "${deb}" Depends)
for d in libusb-1.0-0 libsystemd0 libyaml-cpp "systemd (>= 250)"; do
  grep -q "${d}" <<<"${depends}" || fail "Depends lacks ${d}: ${depends}"
done
! grep -q atlas <<<"${depends}" || fail "Depends names a particular BLAS: ${depends}"
for program in "${work}"/files/usr/bin/*; do
  ! readelf -d "${program}" | grep -E 'NEEDED.*(atlas|openblas|f77blas)' ||
    fail "${program##*/} links a particular BLAS"
done
# The maintainer scripts leave systemd to debhelper's snippets (deb-systemd-invoke, ...).
for s in postinst prerm postrm; do
  [ ! -e "${work}/control/${s}" ] || ! grep -qE '^[^#]*\bsystemctl (start|stop|restart|try-restart|enable)' \
    "${work}/control/${s}" || fail "${s} calls systemctl itself"
done
for s in postinst postrm; do [ -x "${work}/control/${s}" ] || fail "no ${s}"; done
# Control-flow protection (IBT/SHSTK) is not asked: Debian 12's dpkg-buildflags does not give it,
# and Debian 12's static libceres.a, linked into the programs, is built without it.
hardening=$(hardening-check --nocfprotection "${work}"/files/usr/bin/*) ||
  { echo "${hardening}"; fail "hardening-check"; }
grep -q 'Read-only relocations: yes' <<<"${hardening}" || fail "no RELRO: ${hardening}"
grep -q 'Immediate binding: yes' <<<"${hardening}" || fail "no BIND_NOW: ${hardening}"
echo "package $(basename "${deb}"): $(wc -l < "${work}/contents") paths, $(wc -l < \
  "${work}/control/conffiles") conffiles, lintian clean, hardened; Depends: ${depends}"

if [ "$(id -u)" -ne 0 ] || ! command -v systemd-sysusers >/dev/null; then
  echo "not root (or no systemd-sysusers): the install into a scratch root is skipped"
  exit 0
fi
root=${work}/root
mkdir -p "${root}/var/lib/dpkg/info" "${root}/var/lib/dpkg/updates" "${root}/etc"
touch "${root}/var/lib/dpkg/status"
dpkg_root() {
  dpkg --root="${root}" --force-script-chrootless --force-depends --force-not-root \
    --log=/dev/null "$@" >>"${work}/dpkg.log" 2>&1 || { cat "${work}/dpkg.log"; fail "dpkg $*"; }
}
dpkg_root -i "${deb}"
[ -x "${root}${binary}" ] || fail "dpkg -i did not install ${binary}"
gid=$(awk -F: '$1 == "zerocal" { print $3 }' "${root}/etc/group")
[ -n "${gid}" ] || fail "postinst did not make the group zerocal"
grep -q '^zerocal:' "${root}/etc/passwd" || fail "postinst did not make the user zerocal"
token="${root}${confdir}/token"
[ "$(stat -c '%a %u %g' "${token}")" = "640 0 ${gid}" ] ||
  fail "the token is $(stat -c '%a %u %g' "${token}"), not 640 root:zerocal"
[ "$(wc -c < "${token}")" -ge 40 ] || fail "the token is too short"
first_token=$(cat "${token}")

echo "# edited at the cell" >> "${root}${config}"
dpkg_root -i "${deb}"  # a reinstall (an upgrade to the same version): edits and token kept
grep -q "edited at the cell" "${root}${config}" || fail "a reinstall lost the edited ${config}"
[ "$(cat "${token}")" = "${first_token}" ] || fail "a reinstall replaced the token"

dpkg_root -r zerocal
[ ! -e "${root}${binary}" ] || fail "dpkg -r left ${binary}"
[ -f "${root}${config}" ] || fail "dpkg -r removed the conffile ${config} (only purge does)"
[ -f "${token}" ] || fail "dpkg -r removed the token (only purge does)"
dpkg_root -P zerocal
[ ! -e "${root}${config}" ] || fail "dpkg -P left ${config}"
[ ! -e "${token}" ] || fail "dpkg -P left the token"
[ ! -e "${root}${confdir}" ] || fail "dpkg -P left ${confdir}: $(find "${root}${confdir}")"
# Everything happened in the scratch root: nothing of zerocal in this machine's systemd state.
! find /var/lib/systemd/deb-systemd-helper-enabled /var/lib/systemd/deb-systemd-helper-masked \
  -name 'zerocald*' 2>/dev/null | grep -q . ||
  fail "the maintainer scripts wrote zerocald's state into this machine's /var/lib/systemd"
echo "installed, reinstalled, removed and purged in a scratch dpkg root"
