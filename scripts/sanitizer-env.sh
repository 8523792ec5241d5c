# Sourced by sanitize.sh and fuzz.sh: the repository's root, ccache when installed, and the
# sanitizers' run-time options (stop at the first report; the suppressions in scripts/).
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
UBSAN_OPTIONS+=:suppressions=$root/scripts/sanitizer-suppressions.txt
export LSAN_OPTIONS=suppressions=$root/scripts/lsan-suppressions.txt
