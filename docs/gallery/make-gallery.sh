#!/usr/bin/env bash
# Remakes every picture of the README's gallery (docs/gallery/*.png) with the command
# written beside it here; the README's gallery quotes the same commands.
#
#   bash docs/gallery/make-gallery.sh [BUILD_DIR]      # BUILD_DIR holds tearables, tearables-view
#
# Frames are 640x360 (a figure's width in a report; the overlay keeps its share of the
# picture at any size), plots 640x480, the viewer 1280x720 under Xvfb (xvfb-run).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="${1:-build}"
tearables="$build/tearables"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT

# frame NAME ARGS...: `tearables run ARGS... --out DIR`, then DIR/frame_00001.png -> NAME.png
frame() {
    local name="$1"; shift
    "$tearables" run "$@" --quiet --out "$out/$name"
    cp "$out/$name/frame_00001.png" "$here/$name.png"
}
# plot NAME ARGS...: `tearables run ARGS... --out DIR`, then DIR/plot.png -> NAME.png
plot() {
    local name="$1"; shift
    "$tearables" run "$@" --quiet --out "$out/$name"
    cp "$out/$name/plot.png" "$here/$name.png"
}

frame swing              swing --png --size 640x360 --steps 150 --every 150
frame wind-boxes         wind-boxes --png --size 640x360 --steps 300 --every 300
frame rupture-variation  rupture-variation --png --size 640x360 --steps 450 --every 450
plot  rupture-variation-plot rupture-variation --plot --plot-size 640x480
plot  plasticity-plot    plasticity --plot --plot-size 640x480
frame bridge             bridge --png --size 640x360 --steps 370 --every 370
frame bridge-torn        bridge --png --size 640x360 --steps 480 --every 480
frame paper-ball         paper-ball --png --size 640x360 --steps 300 --every 300
frame twist-game         twist-game --png --size 640x360 --steps 555 --every 555
frame telephone-cord     telephone-cord --png --size 640x360 --every 750
frame torsion-nonuniform torsion-nonuniform --png --size 640x360 --every 300
plot  twist-game-plot    twist-game --plot --plot-size 640x480
frame elevator           elevator --png --size 640x360 --steps 170 --every 170
frame elevator-dropped   elevator --png --size 640x360 --steps 250 --every 250
frame banner             banner --png --size 640x360 --steps 190 --every 190
frame banner-torn        banner --png --size 640x360 --steps 230 --every 230
xvfb-run -a -s '-screen 0 1600x1200x24' "$build/tearables-view" swing --size 1280x720 \
    --screenshot "$here/viewer-swing.png" --steps 150
