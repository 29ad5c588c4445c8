#!/usr/bin/env bash
# Regenerates docs/images/convergence-spheres.png: dcs on the shipped
# spheres scene, progressive in sets of 16 samples to a radiance RMSE of
# 2e-3 (docs/progressive.md). The chart's axes are samples, not seconds,
# so it is the same on every machine.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
target/release/penumbra render scenes/spheres.toml -o "$out/spheres.png" \
    --samples 16 --target-error 2e-3 \
    --convergence docs/images/convergence-spheres.png --explain 2>&1 | grep -E "progressive|set " || true
