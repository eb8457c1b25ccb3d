#!/usr/bin/env bash
# Builds everything with AddressSanitizer + UndefinedBehaviorSanitizer and runs the whole
# test suite. Part of CI (.ci/run). Leaks inside third-party libraries are suppressed in
# .ci/lsan.supp; any finding in drape's own code fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
build=${DRAPE_ASAN_BUILD_DIR:-build-asan}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DDRAPE_SANITIZE=ON -DDRAPE_WERROR=ON \
    -DDRAPE_BUILD_BENCHMARKS=OFF -DDRAPE_SIMD=OFF "$@"
cmake --build "$build" -j"$(nproc)"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$PWD/.ci/lsan.supp
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" --timeout 1800
