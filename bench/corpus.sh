#!/usr/bin/env bash
# Runs `dhfcast decompose` and `dhfcast check --input` on the closed meshes of CGAL's data set
# (Debian package libcgal-demo), each scaled so that its longest side is 150 mm, at several seeds,
# default options otherwise. Prints one row per run and, last, the pass rate: a measure of how the
# tool does on models nobody tuned it on.
#
#   bench/corpus.sh [--seeds "1 2 3"] [--models "elephant spool ..."] [--size MM]
#                   [--timeout S] [--build DIR] [--keep DIR]
#
# Meshes that decompose rejects as invalid input (exit code 3: open, non-manifold, ...) are listed
# apart with their one-line error; every other outcome is a run. A run passes when decompose exits
# 0 within --timeout seconds (default 600) and every check of `dhfcast check --input` passes.
# --keep DIR keeps each run's output folder and check report.
set -euo pipefail
source "$(dirname "$0")/common.sh"
seeds="1 2 3"
models=""
size=150
limit=600
keep=""
while [ $# -gt 0 ]; do
  case "$1" in
    --models) models="$2" ;;
    --size) size="$2" ;;
    *) common_option "$1" "${2:-}" || { echo "usage: bench/corpus.sh [--seeds LIST] [--models LIST] [--size MM] [--timeout S] [--build DIR] [--keep DIR]" >&2; exit 2; } ;;
  esac
  shift 2
done
require_build
meshes="$build/testdata/cgal/data/meshes"
[ -d "$meshes" ] || { echo "corpus: no CGAL data set at $meshes (install libcgal-demo, configure again)" >&2; exit 2; }
if [ -z "$models" ]; then
  models="$(cd "$meshes" && ls -- *.off *.obj *.ply *.stl 2>/dev/null | sed 's/\.[^.]*$//' | sort -u | tr '\n' ' ')"
fi

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
printf '%-22s %4s %7s %6s %5s %8s %6s %6s %6s %6s %6s %7s %6s  %s\n' \
  model seed tris tets parts min_part tets_s access segm parts_s molds total peakMB checks
for m in $models; do
  f="$(ls "$meshes/$m".* 2>/dev/null | head -n 1 || true)"
  [ -n "$f" ] || { echo "corpus: no mesh named $m" >&2; continue; }
  for s in $seeds; do
    out="$tmp/$m-$s"
    run_decompose "$limit" "$out" "$tmp/err" "$f" --size "$size" --seed "$s"
    if [ "$rc" -eq 3 ]; then
      echo "  $m: $(grep -m1 'error' "$tmp/err" || head -n 1 "$tmp/err")" >> "$tmp/rejected"
      break  # the input is invalid whatever the seed
    fi
    if [ "$rc" -ne 0 ]; then
      printf '%-22s %4s %7s %6s %5s %8s %6s %6s %6s %6s %6s %7s %6s  FAIL: %s\n' \
        "$m" "$s" - - - - - - - - - - "$peak_mb" "$(failure_reason "$limit" "$tmp/err")"
      continue
    fi
    "$build/dhfcast" check "$out" --input "$f" --size "$size" --json > "$tmp/check.json" 2> "$tmp/check.err" || true
    [ -n "$keep" ] && { mkdir -p "$keep"; rm -rf "${keep:?}/$m-$s"; cp -r "$out" "$keep/$m-$s"; cp "$tmp/check.json" "$keep/$m-$s.check.json"; }
    /usr/bin/python3 - "$m" "$s" "$out" "$peak_mb" "$(check_verdict "$tmp/check.json" "$tmp/check.err")" <<'PY' ||
import json, sys
m, s, out, peak, verdict = sys.argv[1:6]
d = json.load(open(f"{out}/decomposition.json"))
t = d["timings_s"]
volume = d["input"]["volume_mm3"]
smallest = min(p["volume_mm3"] for p in d["parts"]) / volume if volume > 0 else 0
print(f"{m:<22} {s:>4} {d['input']['triangles']:7d} {d['tetrahedra']:6d} {len(d['parts']):5d} "
      f"{100 * smallest:7.3f}% {t['tetrahedralize']:6.1f} {t['accessibility']:6.1f} "
      f"{t['segmentation']:6.1f} {t['parts']:6.1f} {t['molds']:6.1f} {t['total']:7.1f} {peak:>6}  "
      f"{verdict}")
PY
      echo "$m $s  FAIL: unreadable output folder"
  done
done | tee "$tmp/rows"

runs=$(grep -cE '  (PASS|FAIL)' "$tmp/rows" || true)
passes=$(grep -cE '  PASS ' "$tmp/rows" || true)
if [ -s "$tmp/rejected" ]; then
  echo
  echo "rejected as invalid input ($(wc -l < "$tmp/rejected")):"
  cat "$tmp/rejected"
fi
echo
echo "pass rate: $passes of $runs runs"
