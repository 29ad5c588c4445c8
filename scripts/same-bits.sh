#!/usr/bin/env bash
# Proof that a refactoring changed no pixel: renders every shipped scene with
# every technique and its main options, with the binary built from BASE (a
# git revision, default HEAD) and with the working tree, and compares the
# PNG and EXR (all AOV layers) byte for byte.
#
#   scripts/same-bits.sh [BASE] [--base-bin PATH] [--size WxH] [--samples N]
#
# Exit 0 when every pair is identical, 1 otherwise (the differing renders are
# listed). Renders go to target/same-bits/{base,new}.
set -euo pipefail
cd "$(dirname "$0")/.."
base=HEAD base_bin="" size=160x120 samples=16
while [ $# -gt 0 ]; do
  case "$1" in
    --base-bin) base_bin=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --samples) samples=$2; shift 2 ;;
    *) base=$1; shift ;;
  esac
done
w=${size%x*} h=${size#*x}
out=target/same-bits
rm -rf "$out"; mkdir -p "$out/base" "$out/new"
if [ -z "$base_bin" ]; then
  wt=$(mktemp -d)
  git worktree add -q --detach "$wt" "$base"
  CARGO_TARGET_DIR=target/same-bits-build cargo build --release --quiet --manifest-path "$wt/Cargo.toml"
  base_bin=target/same-bits-build/release/penumbra
  git worktree remove --force "$wt"
fi
cargo build --release --quiet
new_bin=target/release/penumbra
# Every registered technique with its defaults, then the main options of
# each (technique name | extra options).
runs=()
for t in $("$new_bin" techniques --names); do runs+=("$t|"); done
runs+=(
  "reference|--pattern sobol"
  "shadow-volumes|--zpass"
  "dcs|--silhouettes centre"
  "dcs|--silhouettes light"
  "dcs|--silhouettes centre --dcs-mode direct"
  "dcs|--silhouettes light --transmittance summed"
  "dcs|--silhouettes centre --coverage bitfield --pattern correlated"
)
aov=depth,position,normal,albedo,mask,vcoef
fail=0 n=0
for scene in scenes/*.toml; do
  s=$(basename "$scene" .toml)
  for run in "${runs[@]}"; do
    t=${run%%|*} opts=${run#*|}
    stem="$s-$t$(echo "$opts" | tr ' ' '_')"
    for which in base new; do
      bin=$base_bin; [ $which = new ] && bin=$new_bin
      # shellcheck disable=SC2086
      if ! "$bin" render "$scene" --technique "$t" $opts --samples "$samples" \
          --width "$w" --height "$h" -o "$out/$which/$stem.png" \
          --exr "$out/$which/$stem.exr" --aov "$aov" 2>"$out/$which/$stem.log"; then
        echo "refused" > "$out/$which/$stem.png"; cp "$out/$which/$stem.png" "$out/$which/$stem.exr"
      fi
    done
    n=$((n + 1))
    if cmp -s "$out/base/$stem.png" "$out/new/$stem.png" && cmp -s "$out/base/$stem.exr" "$out/new/$stem.exr"; then
      :
    else
      echo "DIFFERS: $stem"; fail=$((fail + 1))
    fi
  done
done
echo "same-bits: $((n - fail)) passed, $fail failed"
[ $fail -eq 0 ]
