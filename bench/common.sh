# Defaults and helpers shared by the bench scripts (sourced, not run).
# Models are read from $DHFCAST_MODELS_DIR (default: ../shared/models beside the repository).
here="$(cd "$(dirname "$0")/.." && pwd)"
build="$here/build"
models_dir="${DHFCAST_MODELS_DIR:-$here/../shared/models}"
models="bunny armadillo elephant fertility duck bimba doubletorus dragonstand fandisk rockerarm pinion mastercylinder joint wrench teacup vase"

# Exits when the built executable is missing.
require_build() {
  [ -x "$build/dhfcast" ] || { echo "bench: build first (cmake --build $build)" >&2; exit 2; }
}

# Exits when the models folder or the built executable is missing.
require_models_and_build() {
  [ -d "$models_dir" ] || { echo "bench: no models folder at $models_dir (set DHFCAST_MODELS_DIR)" >&2; exit 2; }
  require_build
}

# common_option NAME VALUE: takes an option that corpus.sh and shapes.sh share (--seeds, --timeout,
# --build, --keep); returns 1 for any other.
common_option() {
  case "$1" in
    --seeds) seeds="$2" ;;
    --timeout) limit="$2" ;;
    --build) build="$2" ;;
    --keep) keep="$2" ;;
    *) return 1 ;;
  esac
}

# run_decompose LIMIT OUT ERR ARGS...: runs `dhfcast decompose ARGS -o OUT --quiet`, killed after
# LIMIT seconds, its stderr in ERR. Sets rc (its exit code; 137 when killed), secs (wall-clock
# seconds) and peak_mb (peak resident memory).
run_decompose() {
  local limit="$1" out="$2" err="$3" start kb
  shift 3
  start=$(date +%s.%N)
  rc=0
  /usr/bin/time -f '%M' -o "$err.mem" timeout --signal=KILL "$limit" \
    "$build/dhfcast" decompose "$@" -o "$out" --quiet 2> "$err" || rc=$?
  secs=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
  kb=$(tail -n 1 "$err.mem" 2>/dev/null | tr -dc '0-9')
  peak_mb=$(( ${kb:-0} / 1024 ))
}

# Why a run failed, in a few words: "exit N" or "over LIMIT s (killed)", and its first error line.
failure_reason() {
  local why="exit $rc"
  [ "$rc" -eq 137 ] && why="over ${1} s (killed)"
  echo "$why: $(grep -m1 'error' "$2" || true)"
}

# check_verdict CHECK_JSON CHECK_ERR: "PASS" or "FAIL", then each check's name:status, from a
# `dhfcast check --json` report; "FAIL check error: ..." when check wrote none.
check_verdict() {
  /usr/bin/python3 - "$1" "$2" <<'PY'
import json, sys
try:
    checks = json.load(open(sys.argv[1]))["checks"]
    passed = all(c["status"] != "fail" for c in checks)
    print("PASS" if passed else "FAIL", " ".join(f"{c['name']}:{c['status']}" for c in checks))
except Exception:  # no report: check itself failed
    print("FAIL check error:", " ".join(open(sys.argv[2]).read().split())[:200])
PY
}
