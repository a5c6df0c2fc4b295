#!/usr/bin/env bash
# Installs zerocal's build and test dependencies from Debian 12's packages.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libceres-dev libboost-dev libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
  libspdlog-dev libfmt-dev libusb-1.0-0-dev libsqlite3-dev
  libssl-dev openssl  # the web terminal's TLS, and the test's self-signed certificate
  libgtest-dev libgmock-dev libbenchmark-dev umockdev libumockdev-dev
  zlib1g-dev chromium
  chromium-driver python3-selenium  # the web terminal's browser test (tests/web/test_browser.py)
  libsystemd-dev systemd dpkg-dev file
  debhelper bash-completion lintian devscripts  # the Debian package, its lintian and hardening-check
  groff-base zsh fish  # the man pages' and the zsh and fish completions' tests
  clang libclang-rt-14-dev  # the fuzz targets: clang++ and its libFuzzer and sanitizer runtimes
)
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
