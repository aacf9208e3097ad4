# Shared checks for the sweep_*_time.sh scripts (sourced, not run; the caller
# defines die).

# require_watergs_workspace BINARY WORKSPACE: dies unless BINARY is the CLI and
# WORKSPACE a COLMAP workspace (images/ and sparse/0/).
require_watergs_workspace() {
  [ -x "$1" ] || die "$1: no watergs executable (build it: cmake --build build --target watergs)"
  [ -d "$2/images" ] || die "$2: not a COLMAP workspace (no images/ folder)"
  [ -d "$2/sparse/0" ] || die "$2: not a COLMAP workspace (no sparse/0 folder)"
}
