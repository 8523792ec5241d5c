#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (clang, AddressSanitizer + UndefinedBehaviorSanitizer) and
# fuzzes each for SECONDS (default 60), one after the other, starting from the seed corpus in
# fuzz/corpus/. Fails on any crash, leak, UBSan report or input slower than 30 s; the input that
# did it is kept as BUILD/crashes/TARGET-*. Prints, per target, the inputs run and the time.
#   scripts/fuzz.sh [SECONDS] [TARGET...]   (targets: stl obj off ply decomposition_json)
# Environment: DHFCAST_FUZZ_BUILD (default build-fuzz), DHFCAST_FUZZ_JOBS (default 2).
set -euo pipefail

seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(stl obj off ply decomposition_json)
source "$(dirname "$0")/sanitizer-env.sh"
build=${DHFCAST_FUZZ_BUILD:-$root/build-fuzz}
jobs=${DHFCAST_FUZZ_JOBS:-2}

cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_COMPILER=clang++ -DDHFCAST_FUZZ=ON -DDHFCAST_BUILD_TESTS=OFF "${launcher[@]}" \
  >/dev/null
cmake --build "$build" -j"$jobs" --target fuzz

mkdir -p "$build/crashes"
summary=()
for t in "${targets[@]}"; do
  corpus="$build/corpus/$t"  # new inputs go here, not into the repository
  mkdir -p "$corpus"
  log="$build/fuzz_$t.log"
  echo "fuzz: $t for $seconds s"
  if ! "$build/fuzz/fuzz_$t" -max_total_time="$seconds" -timeout=30 -max_len=4096 \
      -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$build/crashes/$t-" \
      "$corpus" "$root/fuzz/corpus/$t" >"$log" 2>&1; then
    tail -n 60 "$log"
    echo "fuzz: $t FAILED (log: $log, input: $build/crashes/$t-*)"
    exit 1
  fi
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  time=$(sed -n 's/^stat::.*//; s/^Done \([0-9]*\) runs in \([0-9]*\) second.*/\2/p' "$log")
  summary+=("$t: ${runs:-?} inputs in ${time:-?} s, no crash, leak or UBSan report")
done
printf 'fuzz: %s\n' "${summary[@]}"
