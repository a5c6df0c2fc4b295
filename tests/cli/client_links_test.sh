#!/bin/sh
# The technician's zerocal links no solver, driver, simulator or record: no shared library of
# Ceres, libusb, yaml-cpp, SQLite or their kin, and no symbol of the engine, the drivers, the
# simulated cell or the daemon's record in the program (the static libraries leave their names in
# it). Usage: client_links_test.sh ZEROCAL
set -eu
program=$1
fail=0

shared=$(ldd "$program")
for library in libceres libglog libusb libyaml-cpp libspdlog libsystemd libsqlite3; do
  if printf '%s\n' "$shared" | grep -q "$library"; then
    echo "FAIL: $program links $library:"; printf '%s\n' "$shared" | grep "$library"; fail=1
  fi
done

symbols=$(nm -C "$program"; nm -C -D "$program")
# Fail closed: a stripped program would pass every check below without showing anything.
if ! printf '%s\n' "$symbols" | grep -q 'zerocal::cli::runClient'; then
  echo "FAIL: no zerocal symbols in $program (stripped?): cannot tell what it links"; exit 1
fi
for name in 'ceres::' 'libusb_' 'YAML::' 'zerocal::SimController' 'zerocal::randomWorld(' \
            'zerocal::irc5::' 'zerocal::Irc5Client' 'zerocal::usb1408fs::' 'zerocal::solve(' \
            'zerocal::planPoses(' 'zerocal::service::' 'zerocal::SessionStore' 'zerocal::loadRobot(' \
            'zerocal::record::' 'sqlite3_'; do
  if printf '%s\n' "$symbols" | grep -qF "$name"; then
    echo "FAIL: $program holds $name:"; printf '%s\n' "$symbols" | grep -F "$name" | head -3; fail=1
  fi
done
[ "$fail" -eq 0 ] && echo "zerocal links only the client, the results codec and CLI11"
exit "$fail"
