#!/usr/bin/env bash
# Runs `dhfcast decompose` on the extended models and prints one table: model, triangles, tets,
# seconds per stage (median of RUNS runs), parts, beside the paper's Table 1.
#
#   bench/run.sh [--runs N] [--tets N] [--models "bunny armadillo ..."] [--build DIR] [--keep DIR]
#
# --keep DIR keeps each model's first output folder and its check report in DIR.
#
# Models are read from $DHFCAST_MODELS_DIR (default: ../shared/models beside the repository).
set -euo pipefail
source "$(dirname "$0")/common.sh"
runs=3
tets=""
keep=""
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --tets) tets="$2"; shift 2 ;;
    --models) models="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    *) echo "usage: bench/run.sh [--runs N] [--tets N] [--models LIST] [--build DIR] [--keep DIR]" >&2; exit 2 ;;
  esac
done
require_models_and_build

# Paper's Table 1: tets, DHF s, solve s, partsgen s, parts.
declare -A paper=(
  [bunny]="82234 156 611 130 4" [armadillo]="57681 123 331 124 6" [elephant]="50589 114 264 273 7"
  [fertility]="24215 41 147 104 2" [duck]="94056 157 1911 189 2" [bimba]="59077 236 329 209 5"
  [doubletorus]="19527 28 45 5 1" [dragonstand]="75500 203 484 355 7")

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
printf '%-15s %7s %7s %6s %6s %6s %6s %6s %6s %5s %5s %6s %5s %-24s | %7s %5s %5s %5s %5s\n' \
  model tris tets load tets_s access segm parts total parts cut chk_s dhf% check p.tets p.DHF p.sol p.prt p.#
for m in $models; do
  f="$models_dir/$m.stl"
  [ -f "$f" ] || { echo "bench: skip $m (no $f)" >&2; continue; }
  paper_row="${paper[$m]:-}"
  target="${tets:-${paper_row%% *}}"
  case "$target" in ''|*[!0-9]*) target=50000 ;; esac
  for r in $(seq "$runs"); do
    "$build/dhfcast" decompose "$f" -o "$tmp/$m-$r" --tets "$target" --quiet --force
  done
  # The independent verifier's verdict on the first run's output.
  check_start=$(date +%s.%N)
  "$build/dhfcast" check "$tmp/$m-1" --input "$f" --json > "$tmp/$m-check.json" || true
  check_end=$(date +%s.%N)
  if [ -n "$keep" ]; then
    mkdir -p "$keep"
    rm -rf "${keep:?}/$m"
    cp -r "$tmp/$m-1" "$keep/$m"
    "$build/dhfcast" check "$tmp/$m-1" --input "$f" > "$keep/$m.check.txt" 2>&1 || true
    cp "$tmp/$m-check.json" "$keep/$m.check.json"
  fi
  /usr/bin/python3 - "$m" "$tmp" "$runs" "${paper[$m]:-- - - - -}" "$check_start" "$check_end" <<'PY'
import json, statistics, sys
m, tmp, runs, paper = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4].split()
check_s = float(sys.argv[6]) - float(sys.argv[5])
checks = json.load(open(f"{tmp}/{m}-check.json"))["checks"]
failed = [c["name"] for c in checks if c["status"] == "fail"]
verdict = "PASS" if not failed else "FAIL:" + ",".join(failed)
# The worst part's share of the check's lines that cross a gap deeper than epsilon.
dhf = next(c for c in checks if c["name"] == "dhf")
dhf_share = f"{100 * dhf['figures']['max_violation_fraction']:.2f}" if "figures" in dhf else "-"
docs = [json.load(open(f"{tmp}/{m}-{r}/decomposition.json")) for r in range(1, runs + 1)]
med = lambda k: statistics.median(d["timings_s"][k] for d in docs)
d = docs[0]
cut = f"{sum(1 for p in d['parts'] if p.get('cut_from_input'))}/{len(d['parts'])}"
print(f"{m:<15} {d['input']['triangles']:7d} {d['tetrahedra']:7d} {med('load'):6.1f} "
      f"{med('tetrahedralize'):6.1f} {med('accessibility'):6.1f} {med('segmentation'):6.1f} "
      f"{med('parts'):6.1f} {med('total'):6.1f} {len(d['parts']):5d} {cut:>5} {check_s:6.1f} "
      f"{dhf_share:>5} {verdict:<24} | "
      + " ".join(f"{x:>5}" for x in paper))
PY
done
