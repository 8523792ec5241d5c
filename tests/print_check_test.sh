#!/usr/bin/env bash
# CTest driver: decomposes MODEL (scaled by SCALE) quickly with molds, then runs print_check.sh on
# the output. Exits 77 (skipped) when the model or a tool is missing.
#   tests/print_check_test.sh DHFCAST MODEL SCALE
set -uo pipefail
dhfcast="$1" model="$2" scale="$3"
[ -f "$model" ] || { echo "print_check_test: $model absent (install libcgal-demo)"; exit 77; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
"$dhfcast" decompose "$model" -o "$work/out" --scale "$scale" --tets 3000 --directions 64 \
  --restarts 2 --quiet || exit 1
"$(dirname "$0")/print_check.sh" "$work/out" --slice first
