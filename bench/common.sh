# Defaults and checks shared by the bench scripts (sourced, not run).
# Models are read from $DHFCAST_MODELS_DIR (default: ../shared/models beside the repository).
here="$(cd "$(dirname "$0")/.." && pwd)"
build="$here/build"
models_dir="${DHFCAST_MODELS_DIR:-$here/../shared/models}"
models="bunny armadillo elephant fertility duck bimba doubletorus dragonstand fandisk rockerarm pinion mastercylinder joint wrench teacup vase"

# Exits when the models folder or the built executable is missing.
require_models_and_build() {
  [ -d "$models_dir" ] || { echo "bench: no models folder at $models_dir (set DHFCAST_MODELS_DIR)" >&2; exit 2; }
  [ -x "$build/dhfcast" ] || { echo "bench: build first (cmake --build $build)" >&2; exit 2; }
}
