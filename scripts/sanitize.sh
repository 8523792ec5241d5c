#!/usr/bin/env bash
# Builds dhfcast and its tests with AddressSanitizer and UndefinedBehaviorSanitizer (halting on
# the first report) and runs the default test tier in that build, less the tests labelled
# `repeats` (the same code many times over, run once by the tier's other tests) and `external`
# (an outside program's verdict on output that the tier's other tests make too: Chromium's, the
# slicer's).
#   scripts/sanitize.sh [ctest arguments...]
# Environment: DHFCAST_SANITIZE_BUILD (default build-sanitize), DHFCAST_SANITIZE_JOBS (default 2).
set -euo pipefail

source "$(dirname "$0")/sanitizer-env.sh"
build=${DHFCAST_SANITIZE_BUILD:-$root/build-sanitize}
jobs=${DHFCAST_SANITIZE_JOBS:-2}

# -O1: the sanitizers' usual level; Release's -O3 makes CGAL's files much slower to build.
# The tests run up to about 7 times slower (CGAL-heavy ones): their timeouts are 8 times as long.
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DDHFCAST_SANITIZE=ON \
  -DDHFCAST_TEST_TIMEOUT_FACTOR=8 "${launcher[@]}" >/dev/null
cmake --build "$build" -j"$jobs"

ctest --test-dir "$build" -LE "extended|repeats|external" -j"$jobs" --output-on-failure "$@"
