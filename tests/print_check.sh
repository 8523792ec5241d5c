#!/usr/bin/env bash
# Checks that the mold halves of an output folder are ready to print as they are written: admesh
# (Debian package admesh) must find no defect in any mold STL, and PrusaSlicer (Debian package
# prusa-slicer) must slice one half of each mold, unrotated, without an error or a warning. The
# slicer's bed is made as large as the half (its default, 200 x 200 x 200 mm, is smaller than the
# molds of large parts): this checks the mesh, and each line gives the half's size to compare with
# a printer's.
#
#   tests/print_check.sh OUTDIR [--slice all|first|none]
#
# Prints one line per file and a summary "N passed, N failed"; exits 0 when all passed, 77 when
# a tool is missing (CTest: skipped), 1 otherwise.
set -uo pipefail
outdir="${1:?usage: print_check.sh OUTDIR [--slice all|first|none]}"
slice="first"
[ "${2:-}" = "--slice" ] && slice="${3:-first}"
for tool in admesh prusa-slicer; do
  command -v "$tool" >/dev/null || { echo "print_check: $tool not installed (Debian package $tool)"; exit 77; }
done
shopt -s nullglob
halves=("$outdir"/molds/*.stl)
[ ${#halves[@]} -gt 0 ] || { echo "print_check: no mold STL in $outdir/molds"; exit 1; }

passed=0 failed=0
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
declare -A size  # per file: "X Y Z" extents in mm, from admesh
for f in "${halves[@]}"; do
  report="$(admesh "$f" 2>&1)"
  size[$f]="$(printf '%s\n' "$report" | awk -F'[=,]' '/^Min [XYZ] =/ { printf "%.1f ", $4 - $2 }')"
  # Defects admesh finds (and would repair): each must be zero in the "Original" column.
  problems=""
  for key in "Facets with 1 disconnected edge" "Facets with 2 disconnected edges" \
             "Facets with 3 disconnected edges" "Degenerate facets" "Edges fixed" \
             "Facets removed" "Facets added" "Facets reversed" "Backwards edges" "Normals fixed"; do
    n="$(printf '%s\n' "$report" | grep -m1 "^$key" | sed 's/.*: *\([0-9]*\).*/\1/')"
    [ -z "$n" ] && { problems+=" [$key: not reported]"; continue; }
    [ "$n" != "0" ] && problems+=" [$key: $n]"
  done
  parts="$(printf '%s\n' "$report" | grep -m1 'Number of parts' | sed 's/^Number of parts *: *\([0-9]*\).*/\1/')"
  if [ -z "$problems" ]; then
    echo "PASS admesh $f ($parts shell(s), ${size[$f]% } mm)"
    passed=$((passed + 1))
  else
    echo "FAIL admesh $f:$problems"
    failed=$((failed + 1))
  fi
done

# One half per mold (the up half of each part) or all of them.
to_slice=()
case "$slice" in
  all) to_slice=("${halves[@]}") ;;
  first) to_slice=("$outdir"/molds/*_up.stl); to_slice=("${to_slice[@]:0:1}") ;;
  none) ;;
  *) echo "print_check: --slice takes all, first or none"; exit 1 ;;
esac
for f in "${to_slice[@]}"; do
  gcode="$tmp/$(basename "$f" .stl).gcode"
  read -r sx sy sz <<<"${size[$f]:-0 0 0}"
  bed_x="$(awk -v s="$sx" 'BEGIN { print int(s) + 20 }')"
  bed_y="$(awk -v s="$sy" 'BEGIN { print int(s) + 20 }')"
  height="$(awk -v s="$sz" 'BEGIN { print int(s) + 10 }')"
  # --dont-arrange: sliced where the file puts it (centred on the bed's origin, which --center
  # moves to the bed's middle), not laid out anew.
  prusa-slicer --export-gcode --output "$gcode" --dont-arrange \
    --bed-shape "0x0,${bed_x}x0,${bed_x}x${bed_y},0x${bed_y}" --center "$((bed_x / 2)),$((bed_y / 2))" \
    --max-print-height "$height" "$f" >"$tmp/slicer.log" 2>&1
  status=$?
  # Anything but the start-up trace, progress lines and the closing line is a complaint.
  complaint="$(grep -v -e '^\[.*\] \[trace\]' -e '^[0-9]* => ' -e '^Slicing result exported' \
               "$tmp/slicer.log" | head -1)"
  if [ "$status" -eq 0 ] && [ -s "$gcode" ] && [ -z "$complaint" ]; then
    echo "PASS prusa-slicer $f ($(grep -c '^G1' "$gcode") moves)"
    passed=$((passed + 1))
  else
    echo "FAIL prusa-slicer $f (exit $status): ${complaint:-$(tail -1 "$tmp/slicer.log")}"
    failed=$((failed + 1))
  fi
done
echo "print_check: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
