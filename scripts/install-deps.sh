#!/usr/bin/env bash
# Installs every Debian package that building, testing and benchmarking dhfcast needs.
# Idempotent and non-interactive; run as root (or with sudo available).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libembree-dev libtbb-dev libcgal-dev libgmp-dev libmpfr-dev libboost-dev
  libmaxflow-dev libeigen3-dev libcli11-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcgal-demo  # CGAL's data set: real closed meshes for the example and the default tests
  admesh prusa-slicer  # tests/print_check.sh: mold STLs are sound and slice
  openscad  # tests/shapes/*.scad: the shapes with a known answer, rendered by the tests
  clang libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer targets, sanitized
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
