#!/usr/bin/env bash
# Installs every Debian package obsynth needs to build, test and cross-compile.
# Idempotent: skips apt when every package is already present.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  libginac-dev libcln-dev libflint-dev libflint-arb-dev libgmp-dev libeigen3-dev libfmt-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev clang-format valgrind nlohmann-json3-dev time jq libxml2-utils
  gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO=sudo
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
