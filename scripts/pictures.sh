#!/usr/bin/env bash
# Renders one frame of every shipped scene (samples/scenes/*.json) with drape-run at 320x240
# and writes docs/pictures/<scene>.png plus the contact sheet docs/pictures/scenes.png (the
# frames in file-name order, four to a row, built with ffmpeg's tile filter), one frame
# of the curtain_catch game (docs/pictures/curtain_catch.png), one of the tablecloth_trick
# game (docs/pictures/tablecloth_trick.png: its slow and its fast yank side by side) and two of
# the laundry_line game (docs/pictures/laundry_line.png: a towel carried over the line beside
# it hanging there). The frame is
# the last step of the scene's own duration unless the table below picks an earlier time
# (in simulated seconds) at which more is going on.
# Usage: scripts/pictures.sh [--out DIR] [--bin DIR]
#   Sets up packages (needs root or sudo only if some are missing), builds the four programs
#   in $DRAPE_BUILD_DIR (default build/, Release) and writes the pictures to docs/pictures.
#   --out DIR  writes them to DIR instead.
#   --bin DIR  uses drape-run and the three games as they are in DIR: no setup,
#              no build. The test samples.pictures.match_the_committed_ones renders with this
#              into its build folder and compares the result with docs/pictures.
set -euo pipefail
out=
bin=
while [ $# -gt 0 ]; do
    case "$1" in
    --out) out=$(realpath -m -- "${2:?--out needs a folder}"); shift 2 ;;
    --bin) bin=$(realpath -m -- "${2:?--bin needs a folder}"); shift 2 ;;
    *) echo "pictures: unknown argument '$1' (usage: scripts/pictures.sh [--out DIR] [--bin DIR])" >&2; exit 2 ;;
    esac
done
cd "$(dirname "$0")/.."
out=${out:-docs/pictures}
if [ -z "$bin" ]; then
    ./scripts/setup.sh
    build=${DRAPE_BUILD_DIR:-build}
    cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
    cmake --build "$build" -j"$(nproc)" --target drape-run drape_curtain_catch \
        drape_tablecloth_trick_game drape_laundry_line >/dev/null
    bin=$build/bin
fi
for program in drape-run curtain_catch tablecloth_trick laundry_line; do
    if [ ! -x "$bin/$program" ]; then
        echo "pictures: $bin/$program not found (build it, or leave out --bin)" >&2
        exit 1
    fi
done

# scene name -> simulated seconds to run (empty: the scene's duration)
declare -A at=(
    [curtain_ball]=1.2   # the ball in the curtain (by the end it has dropped out of view)
    [trampoline]=0.8     # the ball pressing into the sheet on its first landing
)

mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
n=0
for scene in samples/scenes/*.json; do
    name=$(basename "$scene" .json)
    args=("$scene" -o "$tmp/$name" --width 320 --height 240 --fps 1 --no-video --quiet)
    if [ -n "${at[$name]:-}" ]; then args+=(--seconds "${at[$name]}"); fi
    "$bin"/drape-run "${args[@]}"
    last=$(ls "$tmp/$name"/frames/frame_*.png | tail -n 1)
    # Re-encoded by ffmpeg with the strongest PNG compression, to keep the repository small.
    ffmpeg -loglevel error -y -i "$last" -compression_level 100 -pred mixed "$out/$name.png"
    cp "$out/$name.png" "$(printf '%s/tile_%02d.png' "$tmp" "$n")"
    n=$((n + 1))
    echo "pictures: $out/$name.png (from $last)"
done
rows=$(((n + 3) / 4))
ffmpeg -loglevel error -y -framerate 1 -i "$tmp/tile_%02d.png" \
    -vf "tile=4x$rows:padding=4:margin=4:color=white" -frames:v 1 \
    -compression_level 100 -pred mixed "$out/scenes.png"
echo "pictures: $out/scenes.png ($n scenes)"

# The game: two scripted throws (the default seed); frame 48 is the second ball in the curtain.
"$bin"/curtain_catch -o "$tmp/curtain_catch" --throws 2 --width 320 --height 240 >/dev/null
ffmpeg -loglevel error -y -i "$tmp/curtain_catch/frames/frame_00048.png" \
    -compression_level 100 -pred mixed "$out/curtain_catch.png"
echo "pictures: $out/curtain_catch.png"

# The tablecloth trick (default seed), both rounds: slow-yank frame 23 (the dishes dragged to
# the table's edge) beside fast-yank frame 9 (the cloth half out, the dishes in place).
"$bin"/tablecloth_trick -o "$tmp/tablecloth_trick" --width 240 --height 180 >/dev/null
ffmpeg -loglevel error -y -i "$tmp/tablecloth_trick/slow/frames/frame_00023.png" \
    -i "$tmp/tablecloth_trick/fast/frames/frame_00009.png" \
    -filter_complex "[0][1]hstack" -compression_level 100 -pred mixed "$out/tablecloth_trick.png"
echo "pictures: $out/tablecloth_trick.png"

# The laundry line (default seed), its first towel: frame 60 (2.4 s, carried over the line by
# its grab) beside frame 139 (let go at 3.1 s, hanging on the line).
"$bin"/laundry_line -o "$tmp/laundry_line" --rounds 1 --width 240 --height 180 >/dev/null
ffmpeg -loglevel error -y -i "$tmp/laundry_line/frames/frame_00060.png" \
    -i "$tmp/laundry_line/frames/frame_00139.png" \
    -filter_complex "[0][1]hstack" -compression_level 100 -pred mixed "$out/laundry_line.png"
echo "pictures: $out/laundry_line.png"
du -ch "$out"/*.png | tail -n 1
