#!/usr/bin/env bash
# Builds drape's libraries and command-line tools with Clang, warnings as errors, and runs the
# core tests. Part of CI (.ci/run): the README's commands build with GCC, and a program's own
# build may use Clang (its multi-versioned kernels and -Wshadow differ from GCC's: a Clang
# build failed for two days before this check existed).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
build=${DRAPE_CLANG_BUILD_DIR:-build-clang}
CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DDRAPE_WERROR=ON \
    -DDRAPE_BUILD_BENCHMARKS=OFF -DDRAPE_BUILD_REPORTS=OFF "$@"
cmake --build "$build" -j"$(nproc)" --target drape_module drape_bullet drape_io drape-run drape_core_tests
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" -R '^core:'
