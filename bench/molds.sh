#!/usr/bin/env bash
# Builds the molds of the extended models and checks them for printing: for each model,
# `dhfcast decompose` (molds included), `dhfcast check`, then tests/print_check.sh (admesh on
# every mold STL, PrusaSlicer on one half). One line per model: parts, molds built, mold seconds,
# the largest block's footprint (mm, to compare with a printer's bed), the molds check's verdict,
# print_check's counts; below it the molds check's line and each print_check failure.
#
#   bench/molds.sh [--models "bunny fandisk ..."] [--build DIR] [--tets N] [--keep DIR]
#
# --keep DIR keeps each model's output folder in DIR.
#
# Models are read from $DHFCAST_MODELS_DIR (default: ../shared/models beside the repository).
set -uo pipefail
source "$(dirname "$0")/common.sh"
tets=""
keep=""
while [ $# -gt 0 ]; do
  case "$1" in
    --models) models="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --tets) tets="--tets $2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    *) echo "usage: bench/molds.sh [--models LIST] [--build DIR] [--tets N] [--keep DIR]" >&2; exit 2 ;;
  esac
done
require_models_and_build
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
printf '%-15s %5s %6s %8s %-9s %-6s %s\n' model parts molds molds_s block_mm check print
for m in $models; do
  out="$work/$m"
  if ! "$build/dhfcast" decompose "$models_dir/$m.stl" -o "$out" --quiet $tets 2>"$work/$m.err"; then
    printf '%-15s decompose failed: %s\n' "$m" "$(tail -1 "$work/$m.err")"
    continue
  fi
  read -r parts built secs block < <(python3 - "$out/decomposition.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
parts = j["parts"]
molds = [p["molds"] for p in parts if "up" in p.get("molds", {})]
# The block with the largest footprint, its longer side first.
footprint = max((sorted(m["block_mm"][:2], reverse=True) for m in molds), default=[0, 0])
print(len(parts), len(molds), round(j.get("timings_s", {}).get("molds", 0.0), 1),
      "%.0fx%.0f" % tuple(footprint))
PY
)
  line="$("$build/dhfcast" check "$out" | grep -m1 '^[A-Z]* *molds ')"
  verdict="${line%% *}"
  "$here/tests/print_check.sh" "$out" --slice first >"$work/$m.print"
  print="$(tail -1 "$work/$m.print" | sed 's/print_check: //')"
  printf '%-15s %5s %6s %8s %-9s %-6s %s\n' "$m" "$parts" "$built" "$secs" "$block" "$verdict" "$print"
  printf '%-15s %s\n' "" "${line:0:160}"
  grep '^FAIL' "$work/$m.print" | sed "s|$out/||; s/^/                /" | cut -c1-176
  if [ -n "$keep" ]; then
    mkdir -p "$keep"
    rm -rf "${keep:?}/$m"
    cp -r "$out" "$keep/$m"
  fi
done
