#!/usr/bin/env bash
# Bakes a canopy with the lightgrid command, then renders it in Bevy under a virtual
# display (Xvfb) on whatever Vulkan driver exists (Mesa's lavapipe works) and saves
# `out/bevy-volume.png`. Bevy is a long first build (about half an hour on two cores).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$here/../.."
out="$root/out/bevy-example"
mkdir -p "$out"
(cd "$root" && cargo run --release -q -p lightgrid -- scene canopy --size 24 -o "$out/canopy.lgrid")
(cd "$root" && cargo run --release -q -p lightgrid -- bake "$out/canopy.lgrid" -o "$out" --name canopy \
  --sky clear --sun 3000 --sun-elevation 40)
cd "$here"
cargo build --release
xvfb-run -a -s "-screen 0 1024x768x24" cargo run --release -- "$out/canopy.json" "$out/bevy-volume.png"
echo "wrote $out/bevy-volume.png"
