#!/usr/bin/env bash
# Profiles one drape-bench case (or drape-run on a scene) under valgrind's callgrind and prints
# the instructions per step and the top functions (callgrind_annotate).
#
#   scripts/profile.sh exp1_35x35/velocity_verlet/stress_ordered
#   scripts/profile.sh scaling/316x316/velocity_verlet/none/threads:1
#   scripts/profile.sh --run samples/scenes/experiment1_suspended_sheet.json 200
#   scripts/profile.sh --perf sheet_256x256/velocity_verlet/none    # perf sampling instead
#
# For a benchmark case only its timed steps are counted: drape-bench toggles callgrind's
# collection around them (no setup, no warm-up step, no state restores), with one repetition.
# For --run, only Cloth::step is counted (inclusive), divided by the steps asked for; the first
# step also pays the initial forces and the stability estimate. Callgrind collects per thread:
# with ClothSettings::threads > 1 the pool's worker threads are not counted.
set -euo pipefail

usage() {
    cat >&2 <<'EOF'
usage: scripts/profile.sh [-b BUILD_DIR] [-n TOP] [-o OUT_DIR] [--perf] CASE
       scripts/profile.sh [-b BUILD_DIR] [-n TOP] [-o OUT_DIR] --run SCENE.json [STEPS]

  CASE        exact drape-bench case name; list them with
              BUILD_DIR/samples/benchmarks/drape-bench --benchmark_list_tests
  --run       profile drape-run on SCENE.json for STEPS steps (default 100), no rendering
  --perf      sample with perf (cpu-clock, 5 repetitions) instead of callgrind: own time per
              function over the whole process, setup included (scaling cases build their
              cloth once, so their steps dominate, but every state restore re-primes the
              stability estimate, drape::estimateMaxAngularFrequency; benchmark cases only)
  -b DIR      build directory (default: $DRAPE_BUILD_DIR or build)
  -n TOP      number of functions to list (default 25)
  -o DIR      keep the raw profile and logs in DIR (default: a temporary directory)
EOF
    exit "${1:-2}"
}

root=$(cd "$(dirname "$0")/.." && pwd)
build=${DRAPE_BUILD_DIR:-$root/build}
top=25
out=""
mode=bench
while [[ $# -gt 0 ]]; do
    case "$1" in
        -b) [[ $# -ge 2 ]] || usage; build=$2; shift 2 ;;
        -n) [[ $# -ge 2 ]] || usage; top=$2; shift 2 ;;
        -o) [[ $# -ge 2 ]] || usage; out=$2; shift 2 ;;
        --run) mode=run; shift ;;
        --perf) mode=perf; shift ;;
        -h|--help) usage 0 ;;
        -*) echo "profile.sh: unknown option $1" >&2; usage ;;
        *) break ;;
    esac
done
[[ $# -ge 1 ]] || usage
[[ $top =~ ^[0-9]+$ ]] || { echo "profile.sh: -n wants a number, got '$top'" >&2; exit 2; }

if [[ -z $out ]]; then
    out=$(mktemp -d /tmp/drape-profile.XXXXXX)
else
    mkdir -p "$out"
fi
out=$(cd "$out" && pwd)
tool=valgrind
[[ $mode == perf ]] && tool=perf
for t in "$tool" python3; do
    command -v "$t" >/dev/null || { echo "profile.sh: $t not found (scripts/setup.sh)" >&2; exit 1; }
done

# Builds the program if the build directory is configured; says how to configure it if not.
program() { # target, path inside the build directory
    if [[ ! -f $build/CMakeCache.txt ]]; then
        echo "profile.sh: $build is not a configured build directory; run" >&2
        echo "  cmake -S $root -B $build -DCMAKE_BUILD_TYPE=Release" >&2
        exit 1
    fi
    cmake --build "$build" --target "$1" -j"$(nproc)" >"$out/build.log" 2>&1 ||
        { echo "profile.sh: building $1 failed, see $out/build.log" >&2; exit 1; }
    echo "$build/$2"
}

annotate() { # callgrind output file
    # Rows of callgrind_annotate without its preamble, the "file:" prefix and the binary name;
    # the inclusive list leaves out the benchmark harness and the C runtime frames.
    rows() { callgrind_annotate --auto=no --threshold=100 "$@" 2>/dev/null |
        awk '/^-+$/ {sep++; next} sep >= 3 && NF && !/^ *Ir/' |
        sed -E 's/ \[[^]]*\]$//; s/^( *[0-9,]+ +\( *[0-9.]+%\)) +[^:]*:/\1  /' | cut -c1-180; }
    echo "--- top $top functions by own instructions (exclusive) ---"
    rows --inclusive=no "$1" | awk -v n="$top" 'NR <= n'
    echo "--- top $top drape functions including callees (inclusive) ---"
    rows --inclusive=yes "$1" | grep -E 'PROGRAM TOTALS|drape::' |
        grep -vE 'runSteps|runScaling|benchmark::' | awk -v n="$top" 'NR <= n'
}

total_ir() { # callgrind output file -> collected instructions
    awk '/^(summary|totals):/ {print $2; exit}' "$1"
}

if [[ $mode == run ]]; then
    scene=$1
    steps=${2:-100}
    [[ -f $scene ]] || { echo "profile.sh: no scene file '$scene'" >&2; exit 1; }
    [[ $steps =~ ^[1-9][0-9]*$ ]] || { echo "profile.sh: STEPS must be a positive integer" >&2; exit 2; }
    run=$(program drape-run bin/drape-run)
    echo "profiling drape-run $scene --steps $steps (callgrind, Cloth::step only) ..." >&2
    valgrind --tool=callgrind --collect-atstart=no --toggle-collect='drape::Cloth::step(double)' \
        --callgrind-out-file="$out/callgrind.out" \
        "$run" "$scene" -o "$out/run" --steps "$steps" --no-render --no-video --quiet \
        >"$out/program.log" 2>"$out/valgrind.log" ||
        { echo "profile.sh: drape-run failed, see $out/program.log and $out/valgrind.log" >&2; exit 1; }
    ir=$(total_ir "$out/callgrind.out")
    echo "scene: $scene, $steps steps"
    echo "instructions in Cloth::step: $ir"
    echo "instructions per step: $(python3 -c "print(f'{$ir / $steps:,.0f}')")"
    annotate "$out/callgrind.out"
    echo "raw profile: $out/callgrind.out"
    exit 0
fi

case_name=$1
bench=$(program drape-bench samples/benchmarks/drape-bench)
# Google Benchmark appends /iterations:N (and /process_time) to the registered names.
case_name=${case_name%%/iterations:*}
filter="--benchmark_filter=^${case_name}(/iterations:.*)?\$"
bench_args=("$filter" --benchmark_repetitions=1 --benchmark_report_aggregates_only=false
    --benchmark_out="$out/bench.json" --benchmark_out_format=json)

if [[ $mode == perf ]]; then
    echo "profiling $case_name (perf record, cpu-clock) ..." >&2
    perf record -e cpu-clock -o "$out/perf.data" "$bench" "${bench_args[@]}" --benchmark_repetitions=5 \
        >"$out/program.log" 2>"$out/perf.log" ||
        { echo "profile.sh: perf record failed, see $out/perf.log" >&2; exit 1; }
    echo "case: $case_name (whole process, setup included)"
    perf report -i "$out/perf.data" --stdio --no-children --sort symbol 2>/dev/null |
        grep -E '^ +[0-9.]+%' | awk -v n="$top" 'NR <= n'
    echo "raw profile: $out/perf.data"
    exit 0
fi

echo "profiling $case_name (callgrind; takes ~50 times the native run time) ..." >&2
valgrind --tool=callgrind --collect-atstart=no --callgrind-out-file="$out/callgrind.out" \
    "$bench" "${bench_args[@]}" >"$out/program.log" 2>"$out/valgrind.log" ||
    { echo "profile.sh: drape-bench failed, see $out/program.log and $out/valgrind.log" >&2; exit 1; }
steps=$(python3 - "$out/bench.json" <<'EOF'
import json, sys
try:
    runs = [b for b in json.load(open(sys.argv[1]))["benchmarks"] if b.get("run_type") == "iteration"]
except (OSError, ValueError):
    runs = []
print(runs[0]["iterations"] if len(runs) == 1 and "error_message" not in runs[0] else 0)
EOF
)
if [[ $steps == 0 ]]; then
    echo "profile.sh: '$case_name' is not exactly one drape-bench case that ran (see" \
        "$out/program.log); the names are:" >&2
    "$bench" --benchmark_list_tests | sed 's|/iterations:.*||' >&2
    exit 1
fi
ir=$(total_ir "$out/callgrind.out")
echo "case: $case_name, $steps timed steps"
echo "instructions collected: $ir"
echo "instructions per step: $(python3 -c "print(f'{$ir / $steps:,.0f}')")"
if [[ $case_name =~ threads:([0-9]+) ]] && (( BASH_REMATCH[1] > 1 )); then
    echo "warning: callgrind toggles collection per thread, so this counts only the thread that" \
        "calls Cloth::step, not the pool's workers; use the threads:1 case for the total work"
fi
annotate "$out/callgrind.out"
echo "raw profile: $out/callgrind.out"
