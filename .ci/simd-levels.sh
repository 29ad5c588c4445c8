# Sourced by .ci/run: the check that every SIMD level gives the same bits.
# Expects $target (the cargo target directory of `cargo test --release`),
# $SIMD_OUT (where the images go) and lap().
#
# The same renders at every level, compared byte for byte (PNG and EXR with
# every AOV). At the baseline they run three times: by the binary `cargo
# test --release` built, by that binary with its run-time dispatch
# (simd::level) held at the baseline (x86-64-forced), and by that build's
# unit-test harness (x86-64-harness: cli::tests::command_lines_from_env
# runs command lines through the command's own entry point). At x86-64-v3
# and, on AVX-512 CPUs, at native, the crate and its dependencies are built
# again with that target-cpu, and only the unit-test harness is built: one
# build of the crate per level, which runs the unit tests (the SIMD facade
# against its scalar twin, kernels against their scalar steps, with the
# facade's lanes in AVX2 rather than SSE halves) and then the renders. The
# harness's baseline images equal the binary's, so the harness stands for
# the binary.
#
# `--target` keeps the proc-macros and build scripts (host code, which
# RUSTFLAGS then leaves alone) out of the per-level rebuilds. The
# dependencies are built for the level but not optimised, except the SIMD
# crates (wide, safe_arch, glam, half): an optimisation level changes no
# bit (Rust does no fast-math and no FMA contraction), the target-cpu is
# what this check is about, and a third of the build time goes.

# Each technique's SIMD paths: raster + stencil, BVH + sampling, wedge
# membership + per-sample counters, semi-opaque transmittance, S-triangle
# look-ups, the STSV add-on, light-view depth maps, the soft shadow map's
# tile accumulation, penumbra casting's volume kernel, PCSS, multi-map and
# adaptive maps. (A third field is the sample count, 16 unless given: DCS's
# sample blocks start at 256.)
SIMD_RUNS=("spheres shadow-volumes" "quad reference" "bunny dcs" "tinted dcs" "fence dcs"
  "spheres dcs 256" "fence wedges" "bunny shadow-map" "spheres soft-shadow-map"
  "spheres penumbra-casting" "quad pcss" "quad multi-map" "quad adaptive-maps")
SIMD_HARNESS=(-- --ignored --exact internal::cli::tests::command_lines_from_env)

# Writes the command lines of level $1 (its output names) to a file and
# prints the file's path. Paths are quoted as shell words.
simd_lines() {
  local level=$1 lines="$SIMD_OUT/command-lines-$1" run scene technique samples name
  : >"$lines"
  for run in "${SIMD_RUNS[@]}"; do
    read -r scene technique samples <<<"$run"
    name="$scene-$technique${samples:+-$samples}-$level"
    printf 'render scenes/%s.toml --technique %s --samples %s --width 320 --height 240 --threads 2 -o %q --exr %q --aov depth,position,normal,albedo,mask,vcoef\n' \
      "$scene" "$technique" "${samples:-16}" "$SIMD_OUT/$name.png" "$SIMD_OUT/$name.exr" >>"$lines"
  done
  echo "$lines"
}

# Builds the unit-test harness at target-cpu $1, runs the unit tests, then
# the renders.
simd_level() {
  local level=$1 lines
  lines=$(simd_lines "$level")
  local build=(--release --quiet --lib --target "$(rustc -vV | sed -n 's/^host: //p')"
    --config 'profile.release.package."*".opt-level=0')
  local crate
  for crate in wide safe_arch glam half; do
    build+=(--config "profile.release.package.$crate.opt-level=3")
  done
  echo "== unit tests at $level"
  CARGO_TARGET_DIR="$target/simd" RUSTFLAGS="-C target-cpu=$level" cargo test "${build[@]}"
  echo "== renders at $level"
  CARGO_TARGET_DIR="$target/simd" RUSTFLAGS="-C target-cpu=$level" \
    PENUMBRA_COMMAND_LINES="$lines" cargo test "${build[@]}" "${SIMD_HARNESS[@]}"
}

# The baseline's renders: x86-64 (the binary), x86-64-forced (the binary,
# dispatch held at the baseline), x86-64-harness (its unit-test harness).
simd_renders() {
  local level=$1 lines line
  lines=$(simd_lines "$level")
  case $level in
    x86-64-harness)
      PENUMBRA_COMMAND_LINES="$lines" cargo test --release --quiet --lib "${SIMD_HARNESS[@]}"
      ;;
    *)
      local run_env=()
      [ "$level" = x86-64-forced ] && run_env=(PENUMBRA_SIMD=baseline)
      while read -r line; do
        eval "local words=($line)"
        env "${run_env[@]}" "$target/release/penumbra" "${words[@]}"
      done <"$lines"
      ;;
  esac
}

# Every image of level $2 equals level $1's, byte for byte.
simd_compare() {
  local a=$1 b=$2 run scene technique samples name
  for run in "${SIMD_RUNS[@]}"; do
    read -r scene technique samples <<<"$run"
    name="$SIMD_OUT/$scene-$technique${samples:+-$samples}"
    cmp "$name-$a.png" "$name-$b.png"
    cmp "$name-$a.exr" "$name-$b.exr"
  done
  echo "$b: bit-identical to $a"
}
