#!/usr/bin/env bash
# Installs every Debian 12 package drape needs to build, test and render.
# Used by the README's two commands and by .ci/run. Needs root (or sudo).
set -euo pipefail

packages=(
    build-essential cmake pkg-config
    libeigen3-dev          # module/: linear algebra, sparse solvers
    libbullet-dev          # integration/: rigid bodies, broadphase, btSoftBody comparison
    libbullet-extras-dev   # Bullet's optional libraries (serialisation, importers)
    libtbb-dev             # integration/: the cloths of a world stepped in parallel
    libassimp-dev          # samples/: mesh import and export
    libosmesa6-dev         # samples/: offscreen OpenGL rendering
    libpng-dev             # samples/: writing PNG frames
    nlohmann-json3-dev     # samples/: scene files
    libcli11-dev           # samples/: command-line parsing
    catch2                 # tests/
    libbenchmark-dev       # benchmarks
    gnuplot-nox            # samples/reports: plots
    clang                  # tests/fuzz: libFuzzer targets (scripts/fuzz.sh)
    clang-format           # scripts/format.sh: the formatting check of scripts/test.sh
    libclang-rt-14-dev     # tests/fuzz: the libFuzzer and sanitizer runtimes
    # samples/: drape-run turns rendered frames into frames.mp4 (H.264) with ffmpeg; the
    # video test checks it with ffprobe (same package) and scripts/pictures.sh builds the
    # contact sheet with its tile filter. Installed for both README commands, the test
    # command included: `apt-get install -y --no-install-recommends ffmpeg` pulls about 90
    # packages and took 33 s on the 2-core reference machine (well under the 2 min we allow
    # an install to add), and without it the video test could not run.
    ffmpeg
)

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -eq 0 ]; then
    echo "setup: all ${#packages[@]} packages already installed"
    exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: installed ${missing[*]}"
