#!/usr/bin/env bash
# PCSS against the hard shadow map and the ray-traced reference on the
# shipped scenes: Vcoef RMSE / mean abs error over every surface pixel
# (`penumbra diff --mask`), and the technique's shadow passes' time
# (`--timings`: the map and the look-up, summed; median of 3 runs).
#
#   scripts/pcss-study.sh [SIZE] [SAMPLES]     (default 256 256)
#
# References are cached in target/bias-study (shared with bias-study.py).
set -euo pipefail
p=${PENUMBRA:-target/release/penumbra}
size=${1:-256}
samples=${2:-256}
out=target/bias-study
mkdir -p "$out"
wh=(--width "$size" --height "$size")
settings=(
  "shadow-map|--technique shadow-map"
  "shadow-map 3x3|--technique shadow-map --pcf 3x3"
  "pcss 16/16|--technique pcss"
  "pcss 16/16 flat receiver|--technique pcss --pcss-flat-receiver"
  "pcss 64/64|--technique pcss --pcss-blocker-samples 64 --pcss-filter-samples 64"
  "pcss box 32²/32²|--technique pcss --pcss-kernel box --pcss-blocker-samples 1024 --pcss-filter-samples 1024"
)
echo "| scene | setting | Vcoef RMSE | MAE | shadow passes (ms) |"
echo "|---|---|--:|--:|--:|"
for scene in ${SCENES:-quad spheres bunny sponza-plants dabrovic}; do
  ref="$out/ref-$scene-$size-$samples.exr"
  if [ ! -e "$ref" ]; then
    "$p" render "scenes/$scene.toml" "${wh[@]}" --technique reference --samples "$samples" \
      -o "$out/ref.png" --exr "$ref" --aov vcoef,mask >/dev/null
  fi
  for s in "${settings[@]}"; do
    name=${s%%|*}
    read -r -a args <<<"${s#*|}"
    times=()
    for run in 1 2 3; do
      ms=$("$p" render "scenes/$scene.toml" "${wh[@]}" "${args[@]}" -o "$out/t.png" \
        --exr "$out/t.exr" --aov vcoef --timings 2>&1 >/dev/null |
        awk '/ms +(shadow map|pcss)/ {s += $1} END {printf "%.1f", s}')
      times+=("$ms")
    done
    median=$(printf '%s\n' "${times[@]}" | sort -g | sed -n 2p)
    read -r rmse mae < <("$p" diff "$out/t.exr" "$ref" --channels-a vcoef.0 --channels-b vcoef.0 \
      --mask "$ref" --json | python3 -c \
      'import json,sys; m=json.load(sys.stdin)["overall"]; print("%.4f %.4f" % (m["rmse"], m["mean_abs"]))')
    echo "| $scene | $name | $rmse | $mae | $median |"
  done
done
