#!/usr/bin/env bash
# The plugin's checks: its unit tests, then the headless test, which renders a sphere
# lit by one live volume in Bevy under a virtual display (Xvfb) on whatever Vulkan
# driver there is (Mesa's lavapipe without a GPU) before and after a sun move, and
# compares the centre pixel with the volume's value (see examples/headless.rs).
#
# Not part of lightgrid's `.ci/run`: Bevy's first build takes about half an hour on two
# cores, which would take CI past its 45 minutes. Needs `xvfb-run` and a Vulkan driver
# (`apt-get install xvfb xauth mesa-vulkan-drivers libvulkan1`, as `.ci/test` does).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here"
out="$here/../../out/bevy-live"
mkdir -p "$out"
export CARGO_INCREMENTAL=0
cargo test --release -j2
cargo build --release -j2 --example headless
xvfb-run -a -s "-screen 0 1024x768x24" cargo run --release -q --example headless -- --save "$out"
echo "frames in $out"
