#!/usr/bin/env bash
# Penumbra casting's translucent pass: its memory
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
render() { # scene label [extra]
  "$bin" render "$1" --technique penumbra-casting --samples "$samples" --width "$w" --height "$h" \
    --threads 1 "${@:3}" -o "$out/$2.png"
}
cpu() { # scene label: user CPU seconds of one run
  TIMEFORMAT=%U; { time render "$1" "$2" > /dev/null 2>&1; } 2>&1
}
explain() { # scene label
  render "$1" "$2" --explain 2> "$out/$2.explain" > /dev/null
  echo "$2:"
  grep -E "penumbra casting light|bit masks|translucent records" "$out/$2.explain" | sed 's/^ */  /'
}
explain scenes/tinted.toml tinted
explain scenes/.tinted-clear.toml tinted-clear
explain scenes/sponza-plants.toml sponza-plants
best_a=999999 best_b=999999
for _ in 1 2 3; do
  a=$(cpu scenes/tinted.toml tinted); b=$(cpu scenes/.tinted-clear.toml tinted-clear)
  best_a=$(echo "if ($a < $best_a) $a else $best_a" | bc); best_b=$(echo "if ($b < $best_b) $b else $best_b" | bc)
done
echo "user CPU (best of 3): tinted $best_a s, tinted with α = 0 $best_b s, ratio $(echo "scale=3; $best_a / $best_b" | bc)"
