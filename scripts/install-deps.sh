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
  zlib1g-dev  # report.html: the meshes are deflated
  chromium python3-pil  # report --png, and the report's test reads its screenshot's pixels
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# npm brings three.js (below); any npm on PATH will do.
command -v npm >/dev/null || missing+=(npm)

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all packages already installed"
else
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# three.js for report.html, at the version package-lock.json pins (inlined into the page at build
# time; see third_party/three/README.md).
three="$(cd "$(dirname "$0")/../third_party/three" && pwd)"
installed="$(node -p "require('$three/node_modules/three/package.json').version" 2>/dev/null || true)"
locked="$(node -p "require('$three/package-lock.json').packages['node_modules/three'].version")"
if [ "$installed" = "$locked" ]; then
  echo "install-deps: three.js $locked already installed"
else
  echo "install-deps: installing three.js $locked (npm ci in third_party/three)"
  (cd "$three" && npm ci --no-audit --no-fund --ignore-scripts)
fi
