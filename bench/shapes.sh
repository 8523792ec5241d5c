#!/usr/bin/env bash
# Decomposes the shapes with a known answer (tests/shapes/*.scad: constructive solids whose least
# number of double-height-field parts is proved in each file's header, see tests/shapes/README.md)
# and compares the number of parts with that minimum: the quick test of part count. Each source
# is rendered to STL by OpenSCAD (Debian package openscad), then `dhfcast decompose` (default
# options, or --tets N) and `dhfcast check OUT --input STL` run on it.
#
#   bench/shapes.sh [--tets N] [--seeds "1 2 3"] [--shapes "pulley mug ..."] [--timeout S]
#                   [--build DIR] [--keep DIR]
#
# One row per run: shape, seed, triangles, tets, minimum, parts, whether an assembly order was
# found, seconds of decompose (wall clock), then PASS when every check passes and each check's
# verdict. Last lines: how many runs reach the minimum, how many stay within minimum + 1, and how
# many pass every check. A run killed after --timeout seconds (default 600) or failing counts as
# none of these. --seeds defaults to "1"; --keep DIR keeps each run's STL, output folder and check
# report.
set -euo pipefail
source "$(dirname "$0")/common.sh"
seeds="1"
tets=""
shapes=""
limit=600
keep=""
while [ $# -gt 0 ]; do
  case "$1" in
    --tets) tets="$2" ;;
    --shapes) shapes="$2" ;;
    *) common_option "$1" "${2:-}" || { echo "usage: bench/shapes.sh [--tets N] [--seeds LIST] [--shapes LIST] [--timeout S] [--build DIR] [--keep DIR]" >&2; exit 2; } ;;
  esac
  shift 2
done
require_build
command -v openscad > /dev/null || { echo "shapes: no openscad (Debian package openscad)" >&2; exit 2; }
sources="$here/tests/shapes"
if [ -z "$shapes" ]; then
  shapes="$(cd "$sources" && ls -- *.scad | sed 's/\.scad$//' | tr '\n' ' ')"
fi

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
printf '%-15s %4s %6s %6s %3s %5s %5s %7s  %s\n' shape seed tris tets min parts order seconds checks
for s in $shapes; do
  src="$sources/$s.scad"
  [ -f "$src" ] || { echo "shapes: no shape named $s" >&2; continue; }
  minimum="$(sed -n 's|^// minimum_parts: *\([0-9][0-9]*\).*|\1|p' "$src" | head -n 1)"
  stl="$tmp/$s.stl"
  if ! openscad -o "$stl" "$src" > "$tmp/openscad.log" 2>&1; then
    printf '%-15s %4s %6s %6s %3s %5s %5s %7s  FAIL: openscad: %s\n' "$s" - - - "${minimum:--}" - - - \
      "$(grep -m1 -i 'error' "$tmp/openscad.log" || true)"
    continue
  fi
  for seed in $seeds; do
    out="$tmp/$s-$seed"
    run_decompose "$limit" "$out" "$tmp/err" "$stl" --seed "$seed" ${tets:+--tets "$tets"}
    if [ "$rc" -ne 0 ]; then
      printf '%-15s %4s %6s %6s %3s %5s %5s %7s  FAIL: %s\n' "$s" "$seed" - - "${minimum:--}" - - \
        "$secs" "$(failure_reason "$limit" "$tmp/err")"
      continue
    fi
    "$build/dhfcast" check "$out" --input "$stl" --json > "$tmp/check.json" 2> "$tmp/check.err" || true
    if [ -n "$keep" ]; then
      mkdir -p "$keep"
      rm -rf "${keep:?}/$s-$seed"
      cp -r "$out" "$keep/$s-$seed"
      cp "$stl" "$keep/$s.stl"
      cp "$tmp/check.json" "$keep/$s-$seed.check.json"
    fi
    /usr/bin/python3 - "$s" "$seed" "${minimum:--}" "$secs" "$out" "$(check_verdict "$tmp/check.json" "$tmp/check.err")" <<'PY' ||
import json, sys
s, seed, minimum, secs, out, verdict = sys.argv[1:7]
d = json.load(open(f"{out}/decomposition.json"))
order = "yes" if d.get("assembly_found") else "no"
print(f"{s:<15} {seed:>4} {d['input']['triangles']:6d} {d['tetrahedra']:6d} {minimum:>3} "
      f"{len(d['parts']):5d} {order:>5} {float(secs):7.1f}  {verdict}")
PY
      echo "$s $seed  FAIL: unreadable output folder"
  done
done | tee "$tmp/rows"

# Rows of finished runs: column 5 is the minimum, column 6 the parts.
runs=$(grep -cE '^[^ ]+ +[0-9]+ ' "$tmp/rows" || true)
at_min=$(awk '$6 ~ /^[0-9]+$/ && $6 <= $5' "$tmp/rows" | wc -l)
near_min=$(awk '$6 ~ /^[0-9]+$/ && $6 <= $5 + 1' "$tmp/rows" | wc -l)
passes=$(grep -cE '  PASS ' "$tmp/rows" || true)
echo
echo "at the minimum: $at_min of $runs runs"
echo "at most minimum + 1: $near_min of $runs runs"
echo "pass every check: $passes of $runs runs"
