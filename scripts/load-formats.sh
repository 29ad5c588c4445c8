#!/usr/bin/env bash
# Load time and peak memory of a scene read from its OBJ and from the same
# model exported to GLB (and PLY where there is one): `penumbra info`
# (load and print only), median of N runs (default 5) of wall time
# (milliseconds, the process from start to exit) and maximum resident size
# (GNU time). Usage:
#   scripts/load-formats.sh [N]      (after cargo build --release)
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-5}
bin=${PENUMBRA_BIN:-target/release/penumbra}
tmp=$(mktemp -d scenes/.load-formats-XXXXXX)
trap 'rm -rf "$tmp"' EXIT
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
measure() { # scene label
  local times=() mems=() i
  for ((i = 0; i < n; i++)); do
    local start end m
    start=$(date +%s%N)
    m=$(/usr/bin/time -f "%M" "$bin" info "$1" 2>&1 >/dev/null | tail -1)
    end=$(date +%s%N)
    times+=("$(((end - start) / 1000000))") mems+=("$m")
  done
  printf '%-32s %6s ms %7s MiB\n' "$2" \
    "$(printf '%s\n' "${times[@]}" | median)" \
    "$(printf '%s\n' "${mems[@]}" | median | awk '{printf "%.1f", $1 / 1024}')"
}
variant() { # scene model-from model-to
  sed "s|$2|$3|" "scenes/$1.toml" >"$tmp/$1-$(basename "$3").toml"
  # The copy sits one folder down: paths go up one.
  sed -i "s|= \"models/|= \"../models/|; s|= \"\([a-z-]*\.png\)\"|= \"../\1\"|" "$tmp/$1-$(basename "$3").toml"
  echo "$tmp/$1-$(basename "$3").toml"
}
echo "median of $n runs of \`penumbra info\` ($(git rev-parse --short HEAD), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs))"
measure scenes/dabrovic.toml "dabrovic: OBJ"
measure "$(variant dabrovic sponza.obj exports/sponza.glb)" "dabrovic: GLB (trimesh)"
measure scenes/bunny.toml "bunny: OBJ"
measure "$(variant bunny stanford-bunny.obj exports/stanford-bunny.glb)" "bunny: GLB (trimesh)"
measure "$(variant bunny stanford-bunny.obj exports/stanford-bunny-binary.ply)" "bunny: binary PLY (trimesh)"
measure "$(variant bunny stanford-bunny.obj exports/stanford-bunny-ascii.ply)" "bunny: ASCII PLY (trimesh)"
