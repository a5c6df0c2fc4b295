#!/usr/bin/env bash
# The Debian package (cpack -G DEB): what it holds (the unit's zerocald, the configuration as
# conffiles, the udev rule, sysusers file, RAPID module, man pages, completion), what it depends
# on, and, when run as root, a real install into a scratch dpkg root (dpkg --root, maintainer
# scripts run with DPKG_ROOT there): the user and group made, the token made root:zerocal 0640, a
# technician's edit of a conffile kept over a reinstall, the purge removing the token.
# Usage: debian_package_test.sh BUILD_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
work=$(mktemp -d)
trap 'rm -rf "${work}"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

(cd "${work}" && cpack -G DEB --config "${build}/CPackConfig.cmake" -B "${work}/out" >cpack.log 2>&1) ||
  { cat "${work}/cpack.log"; fail "cpack -G DEB failed"; }
deb=$(ls "${work}"/out/*.deb)
dpkg-deb -c "${deb}" | awk '{ print $6 }' | sed 's#^\./#/#; s#/$##' > "${work}/contents"
has() { grep -qx "$1" "${work}/contents" || fail "the package lacks $1"; }

dpkg-deb -e "${deb}" "${work}/control"
unit=$(grep '/zerocald.service$' "${work}/contents") || fail "the package has no zerocald.service"
dpkg-deb --fsys-tarfile "${deb}" | tar -xO ".${unit}" > "${work}/zerocald.service"
binary=$(sed -n 's/^ExecStart=\([^ ]*\).*/\1/p' "${work}/zerocald.service")
config=$(sed -n 's/^ExecStart=.*--config \([^ ]*\).*/\1/p' "${work}/zerocald.service")
prefix=${binary%/bin/zerocald}
confdir=${config%/*}
has "${binary}"
has "${prefix}/bin/zerocal"
has "${prefix}/bin/zerocal-lab"
has "${config}"
has "${confdir}/zerocald.d"
has "${confdir}/robots/irb1600-10-145.yaml"
has "${prefix}/share/zerocal/rapid/ZerocalServer.mod"
has "${prefix}/share/zerocal/web/index.html"  # the web terminal, where web.root finds it
has "${prefix}/share/man/man8/zerocald.8"
has "${prefix}/share/man/man1/zerocal.1"
has "${prefix}/share/man/man1/zerocal-lab.1"
has "${prefix}/share/bash-completion/completions/zerocal"
grep -q '/60-zerocal-usb1408fs.rules$' "${work}/contents" || fail "the package lacks the udev rule"
grep -q '/sysusers.d/zerocal.conf$' "${work}/contents" || fail "the package lacks sysusers.d"
! grep -q "${confdir}/token" "${work}/contents" || fail "the package ships a token"

# Every file under /etc is a conffile, and the conffiles exist.
dpkg-deb -c "${deb}" | awk '$1 ~ /^-/ { print $6 }' | sed 's#^\./#/#' > "${work}/files"
grep '^/etc/' "${work}/files" | while read -r f; do
  grep -qx "${f}" "${work}/control/conffiles" || fail "${f} is not a conffile"
done
while read -r f; do has "${f}"; done < "${work}/control/conffiles"
depends=$(dpkg-deb -f "${deb}" Depends)
for d in libusb-1.0-0 libsystemd0 libyaml-cpp "systemd (>= 250)"; do
  grep -q "${d}" <<<"${depends}" || fail "Depends lacks ${d}: ${depends}"
done
for s in postinst prerm postrm; do [ -x "${work}/control/${s}" ] || fail "no ${s}"; done
echo "package $(basename "${deb}"): $(wc -l < "${work}/contents") paths, $(wc -l < \
  "${work}/control/conffiles") conffiles, Depends: ${depends}"

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
dpkg_root -P zerocal
[ ! -e "${root}${config}" ] || fail "dpkg -P left ${config}"
[ ! -e "${token}" ] || fail "dpkg -P left the token"
echo "installed, reinstalled, removed and purged in a scratch dpkg root"
