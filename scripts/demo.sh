#!/usr/bin/env bash
# The README's first command: installs the Debian packages, builds the runner and runs the
# paper's Experiment II (a tablecloth dropped on a desk), writing PNG frames, the final mesh
# (OBJ), per-frame statistics (CSV) and a summary to out/experiment2/.
# Usage: scripts/demo.sh [scene.json] [output folder]
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
scene=${1:-samples/scenes/experiment2_tablecloth.json}
out=${2:-out/experiment2}
build=${DRAPE_BUILD_DIR:-build}
# The same configuration as scripts/test.sh (warnings as errors), so that the test command
# run afterwards reuses what this one built instead of rebuilding it with other flags.
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DDRAPE_WERROR=ON
cmake --build "$build" -j"$(nproc)" --target drape-run
"$build"/bin/drape-run "$scene" -o "$out"
echo "frames and results in $out/"
