#!/usr/bin/env bash
# The plugin's checks: its unit tests, then the headless test, which renders a sphere
# lit by one live volume in Bevy under a virtual display (Xvfb) on whatever Vulkan
# driver there is (Mesa's lavapipe without a GPU) before and after a sun move, and
# compares the centre pixel with the volume's value (see examples/headless.rs). With
# `--baked` it also bakes a canopy with the lightgrid command and renders it through the
# `baked` example (spheres lit by the baked volume alone): out/bevy-live/canopy.png.
#
# Not part of lightgrid's `.ci/run`: Bevy's first build takes about 18 minutes on two
# cores, which would take CI past its 45 minutes. Needs `xvfb-run` and a Vulkan driver
# (`apt-get install xvfb xauth mesa-vulkan-drivers libvulkan1`, as `.ci/test` does).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$here/../.."
out="$root/out/bevy-live"
mkdir -p "$out"
export CARGO_INCREMENTAL=0
cd "$here"
cargo test --release -j2
cargo build --release -j2 --examples
xvfb-run -a -s "-screen 0 1024x768x24" cargo run --release -q --example headless -- --save "$out"
if [[ "${1:-}" == "--baked" ]]; then
  (cd "$root" && cargo run --release -q -p lightgrid -- scene canopy --size 24 -o "$out/canopy.lgrid")
  (cd "$root" && cargo run --release -q -p lightgrid -- bake "$out/canopy.lgrid" -o "$out" --name canopy \
    --sky daylight --sun-from-sky --sun-elevation 40 --unit-scale 0.05)
  xvfb-run -a -s "-screen 0 1024x768x24" cargo run --release -q --example baked -- "$out/canopy.json" "$out/canopy.png"
fi
echo "frames in $out"
