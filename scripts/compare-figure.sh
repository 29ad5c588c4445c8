#!/usr/bin/env bash
# Regenerates docs/images/compare-spheres-flip.png (and -radiance.png):
# the exact techniques on the shipped spheres scene at 256², FLIP and
# radiance RMSE against time, at 4, 16 and 64 samples and run to an
# estimated radiance RMSE of 3e-3 (compare --target-error). Times are this
# machine's; the chart's title says nothing of it, docs/compare.md does.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
target/release/penumbra compare scenes/spheres.toml --width 256 --height 256 \
    --samples 4,16,64 --target-error 3e-3 --out "$out" --no-images
cp "$out/flip_vs_time.png" docs/images/compare-spheres-flip.png
cp "$out/radiance_vs_time.png" docs/images/compare-spheres-radiance.png
grep -E "^\| (dcs|penumbra-casting|reference)" "$out/results.md" | head -12
