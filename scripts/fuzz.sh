#!/usr/bin/env bash
# Builds the libFuzzer targets with Clang and runs each for a bounded time.
#
#   scripts/fuzz.sh [seconds] [target ...]     (default: 600 seconds, fuzz_scene and fuzz_mesh)
#
# The targets run one after the other, each for `seconds`. Seeds: samples/scenes/*.json,
# samples/meshes/* (prefixed here with their format byte, see tests/fuzz/harness.hpp) and the
# small hand-made inputs in tests/fuzz/corpus/. New inputs the fuzzer finds go to
# build-fuzz/corpus/<target>/ and are reused by the next run; crashing inputs go to
# build-fuzz/artifacts/<target>/. Exits non-zero if any target crashed, hung, leaked or ran out
# of memory. See tests/fuzz/README.md.
set -euo pipefail

cd "$(dirname "$0")/.."
root=$(pwd)
seconds=${1:-600}
shift || true
targets=("$@")
[ "${#targets[@]}" -gt 0 ] || targets=(fuzz_scene fuzz_mesh)
if ! [[ "$seconds" =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
    echo "fuzz: usage: scripts/fuzz.sh [seconds] [fuzz_scene|fuzz_mesh ...]" >&2
    exit 2
fi
command -v clang++ >/dev/null || { echo "fuzz: clang++ not found (scripts/setup.sh installs it)" >&2; exit 2; }

build=${DRAPE_FUZZ_BUILD_DIR:-$root/build-fuzz}
# Once the top level adds tests/fuzz itself (see tests/fuzz/README.md), configure from there;
# until then tests/fuzz is its own top level with drape underneath.
source_dir=$root/tests/fuzz
if grep -q 'tests/fuzz' "$root/CMakeLists.txt"; then source_dir=$root; fi

# -O1 keeps the sanitizers' reports readable; no NDEBUG, so assertions (Eigen's included) fire.
CC=clang CXX=clang++ cmake -S "$source_dir" -B "$build" -DDRAPE_BUILD_FUZZERS=ON \
    -DDRAPE_BUILD_TESTS=OFF -DDRAPE_BUILD_BENCHMARKS=OFF -DDRAPE_BUILD_REPORTS=OFF \
    -DDRAPE_WITH_RENDERING=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" >/dev/null
cmake --build "$build" --target "${targets[@]/#/drape_}" -j "${DRAPE_FUZZ_BUILD_JOBS:-2}"

# Mesh seeds: each shipped mesh behind the byte that selects its extension.
mesh_seeds=$build/seeds/fuzz_mesh
rm -rf "$mesh_seeds" && mkdir -p "$mesh_seeds"
for f in "$root"/samples/meshes/*; do
    case "${f##*.}" in
        obj) byte='\x00' ;; ply) byte='\x01' ;; stl) byte='\x02' ;; 3ds) byte='\x03' ;;
        gltf) byte='\x04' ;; glb) byte='\x05' ;; off) byte='\x06' ;; fbx) byte='\x07' ;;
        dae) byte='\x08' ;; *) continue ;;
    esac
    { printf "$byte"; cat "$f"; } >"$mesh_seeds/$(basename "$f")"
done

# fuzz_mesh's scratch files live in the build folder; a killed run leaves nothing in /tmp.
export TMPDIR=$build/tmp
mkdir -p "$TMPDIR"
# Leaks inside Debian's assimp are not drape's (see tests/fuzz/lsan.supp).
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"

status=0
for target in "${targets[@]}"; do
    case $target in
        fuzz_scene) seeds=("$root/samples/scenes" "$root/tests/fuzz/corpus/scene")
                    extra=(-dict="$root/tests/fuzz/scene.dict") ;;
        fuzz_mesh)  seeds=("$mesh_seeds" "$root/tests/fuzz/corpus/mesh"); extra=() ;;
        *) echo "fuzz: unknown target $target" >&2; exit 2 ;;
    esac
    corpus=$build/corpus/$target
    artifacts=$build/artifacts/$target
    log=$build/logs/$target.log
    mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
    echo "fuzz: $target for ${seconds} s (log: $log)"
    touch "$build/logs/$target.start"
    rc=0
    "$build/fuzz/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="$artifacts/" "${extra[@]}" \
        "$corpus" "${seeds[@]}" >"$log" 2>&1 || rc=$?
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    took=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log" | tail -n 1)
    echo "fuzz: $target: ${runs:-?} inputs executed in ${took:-?} s, corpus $(ls "$corpus" | wc -l) files, exit code $rc"
    if [ "$rc" -ne 0 ]; then
        status=1
        echo "fuzz: $target FAILED; the end of its log:" >&2
        tail -n 40 "$log" >&2
        echo "fuzz: inputs saved by this run:" >&2
        find "$artifacts" -type f -newer "$build/logs/$target.start" >&2
    fi
done
exit $status
