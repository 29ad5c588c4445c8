#!/usr/bin/env bash
# Penumbra casting's translucent pass (issue 16, points 5a/5b): its memory
# (--explain's translucent records against the bit masks) and its time, as
# a ratio robust to machine load: instructions (perf stat, --threads 1) of
# the scene against the same scene with every constant opacity set to 0
# (α = 0 casts nothing, so the panes stay receivers but cast no shadow),
# and --explain's wall time of the pass against the opaque casting.
#
#   scripts/pc-translucent-cost.sh [--size WxH] [--samples N]
#
# Needs target/release/penumbra (cargo build --release) and perf.
set -euo pipefail
cd "$(dirname "$0")/.."
size=512x512 samples=256
while [ $# -gt 0 ]; do
  case "$1" in
    --size) size=$2; shift 2 ;;
    --samples) samples=$2; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
w=${size%x*} h=${size#*x}
bin=target/release/penumbra
out=target/pc-translucent
mkdir -p "$out"
# The α = 0 twin of tinted (written next to the original: relative paths).
sed -E 's/opacity = 0\.[0-9]+/opacity = 0.0/' scenes/tinted.toml > scenes/.tinted-clear.toml
trap 'rm -f scenes/.tinted-clear.toml' EXIT
run() { # scene label
  "$bin" render "$1" --technique penumbra-casting --samples "$samples" --width "$w" --height "$h" \
    --threads 1 --explain -o "$out/$2.png" 2> "$out/$2.explain" > /dev/null
  perf stat -x, -e instructions -o "$out/$2.perf" "$bin" render "$1" --technique penumbra-casting \
    --samples "$samples" --width "$w" --height "$h" --threads 1 -o "$out/$2.png" > /dev/null 2>&1
  local ins; ins=$(grep instructions "$out/$2.perf" | cut -d, -f1)
  echo "$2: $ins instructions"
  grep -E "penumbra casting light|bit masks|translucent records" "$out/$2.explain" | sed 's/^ */  /'
}
run scenes/tinted.toml tinted
run scenes/.tinted-clear.toml tinted-clear
run scenes/sponza-plants.toml sponza-plants
a=$(grep instructions "$out/tinted.perf" | cut -d, -f1)
b=$(grep instructions "$out/tinted-clear.perf" | cut -d, -f1)
echo "tinted / tinted with α = 0: $(echo "scale=3; $a / $b" | bc) × the instructions"
