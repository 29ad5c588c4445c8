#!/usr/bin/env bash
# Wall time of one compare sweep as 1 shard and as 4 shards on a running
# Slurm cluster (scripts/slurm-local.sh start), from submission to the
# merged results, for docs/cluster.md. Run on a quiet machine:
#
#   scripts/slurm-local.sh start && export SLURM_CONF=/tmp/penumbra-slurm/slurm.conf
#   scripts/cluster-walltime.sh [target/release/penumbra]
#
# The references are computed first into a shared cache so that both
# sweeps time the runs only (the reference is a one-off cost per scene).
set -euo pipefail
bin="$(realpath "${1:-target/release/penumbra}")"
work=$(mktemp -d /tmp/penumbra-walltime.XXXXXX)
args=(scenes/spheres.toml scenes/bunny.toml --techniques shadow-volumes,dcs,wedges,shadow-map
  --samples 16,64 --reference-samples 256 --repeat 1 --width 320 --height 240 --no-images
  --cache-dir "$work/cache")
"$bin" compare "${args[@]}" --references-only --out "$work/refs" >/dev/null 2>&1

wait_job() { # until the job has left the queue and is COMPLETED
  local id=$1 s
  while :; do
    s=$(scontrol show job "$id" 2>/dev/null | grep -o 'JobState=[A-Z_]*' | sort -u)
    case "$s" in *PENDING* | *RUNNING* | *COMPLETING* | "") sleep 0.2 ;; *) break ;; esac
  done
  [ "$s" = "JobState=COMPLETED" ] || { echo "job $id: $s" >&2; exit 1; }
}

for n in 1 4; do
  t0=$(date +%s.%N)
  out=$("$bin" sweep --slurm --shards "$n" --out "$work/s$n" --submit --cpus-per-task 1 -- "${args[@]}")
  merge=$(sed -n 's/^merge job \([0-9]*\).*/\1/p' <<<"$out")
  wait_job "$merge"
  t1=$(date +%s.%N)
  printf '%d shard(s): %.1f s wall, submission to merged results\n' "$n" "$(echo "$t1 - $t0" | bc)"
done
rm -rf "$work"
