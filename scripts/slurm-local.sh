#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for tests/it/slurm.rs and for
# trying `penumbra sweep --slurm` (docs/cluster.md).
#
#   scripts/slurm-local.sh start    install (Debian packages), configure, start
#   scripts/slurm-local.sh status   daemons, node state, queue
#   scripts/slurm-local.sh stop     stop the daemons this script started
#
# Needs root (apt-get, munged's key, slurmd). No systemd: munged runs as the
# munge user (as root it refuses without --force), slurmctld and slurmd in
# the foreground (-D) in the background of this shell; their PIDs go to
# $STATE/*.pid and `stop` kills exactly those. Exit status: 0 on success,
# 3 when Slurm cannot be installed or started here (callers print the
# reason and skip), 1 on other errors.
#
# Environment: PENUMBRA_SLURM_STATE (default /tmp/penumbra-slurm) holds the
# configuration, spool, logs and PID files.
set -uo pipefail

STATE="${PENUMBRA_SLURM_STATE:-/tmp/penumbra-slurm}"
CONF="$STATE/slurm.conf"
export SLURM_CONF="$CONF"

die() { echo "slurm-local: $*" >&2; exit 1; }
unavailable() { echo "slurm-local: unavailable: $*" >&2; exit 3; }

alive() { [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

install() {
  if command -v slurmctld >/dev/null && command -v slurmd >/dev/null &&
    command -v sbatch >/dev/null && command -v munged >/dev/null; then
    return
  fi
  [ "$(id -u)" = 0 ] || unavailable "not root, and Slurm is not installed"
  command -v apt-get >/dev/null || unavailable "no apt-get (Debian packages expected)"
  echo "slurm-local: installing slurmctld slurmd slurm-client munge"
  export DEBIAN_FRONTEND=noninteractive
  if ! apt-get install -y -q --no-install-recommends slurmctld slurmd slurm-client munge \
    >"$STATE/apt.log" 2>&1; then
    apt-get update -q >>"$STATE/apt.log" 2>&1 || true
    apt-get install -y -q --no-install-recommends slurmctld slurmd slurm-client munge \
      >>"$STATE/apt.log" 2>&1 || unavailable "apt-get install failed (see $STATE/apt.log)"
  fi
}

configure() {
  mkdir -p "$STATE/spool/ctld" "$STATE/spool/d" "$STATE/log" /run/munge /var/log/munge \
    /var/lib/munge /etc/munge
  chown munge:munge /run/munge /var/log/munge /var/lib/munge /etc/munge
  chmod 0755 /run/munge
  if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
  fi
  chown munge:munge /etc/munge/munge.key
  chmod 0400 /etc/munge/munge.key
  local host node cpus
  host=$(hostname -s)
  # The node's own description (CPUs, sockets, memory) from slurmd -C.
  node=$(slurmd -C 2>/dev/null | grep '^NodeName=') ||
    unavailable "slurmd -C printed no node line"
  cpus=$(sed -n 's/.*CPUs=\([0-9]*\).*/\1/p' <<<"$node")
  cat >"$CONF" <<EOF
# Written by scripts/slurm-local.sh: one node, no accounting, no cgroups.
ClusterName=penumbra-local
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$STATE/spool/ctld
SlurmdSpoolDir=$STATE/spool/d
SlurmctldPidFile=$STATE/slurmctld.pidfile
SlurmdPidFile=$STATE/slurmd.pidfile
SlurmctldLogFile=$STATE/log/slurmctld.log
SlurmdLogFile=$STATE/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SchedulerType=sched/backfill
# A failed shard must cancel the merge that waits for it (22.05 reads this
# here, not under SchedulerParameters); otherwise it pends forever.
DependencyParameters=kill_invalid_depend
# Finished jobs stay visible to scontrol for this long (no accounting).
MinJobAge=600
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
$node State=UNKNOWN
PartitionName=debug Nodes=${host} Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
  echo "$cpus" >"$STATE/cpus"
}

start() {
  mkdir -p "$STATE"
  if alive "$STATE/slurmctld.pid" && alive "$STATE/slurmd.pid"; then
    echo "slurm-local: already running (SLURM_CONF=$CONF)"
    return
  fi
  install
  configure
  if ! alive "$STATE/munged.pid"; then
    setpriv --reuid=munge --regid=munge --clear-groups /usr/sbin/munged -F \
      >"$STATE/log/munged.out" 2>&1 &
    echo $! >"$STATE/munged.pid"
  fi
  for _ in $(seq 50); do [ -S /run/munge/munge.socket.2 ] && break; sleep 0.1; done
  [ -S /run/munge/munge.socket.2 ] || unavailable "munged did not start ($STATE/log/munged.out)"
  # -i: ignore state a previous cluster left in the spool.
  slurmctld -D -i -f "$CONF" >"$STATE/log/slurmctld.out" 2>&1 &
  echo $! >"$STATE/slurmctld.pid"
  sleep 1
  slurmd -D -f "$CONF" >"$STATE/log/slurmd.out" 2>&1 &
  echo $! >"$STATE/slurmd.pid"
  local state=""
  for _ in $(seq 60); do
    state=$(sinfo -h -N -o '%T' 2>/dev/null | head -1)
    case "$state" in idle | mixed | allocated) break ;; esac
    alive "$STATE/slurmctld.pid" || break
    sleep 0.5
  done
  case "$state" in
  idle | mixed | allocated)
    echo "slurm-local: node $(hostname -s) $state; export SLURM_CONF=$CONF" ;;
  *)
    tail -5 "$STATE/log/slurmctld.log" "$STATE/log/slurmd.log" >&2 2>/dev/null
    stop
    unavailable "the node did not become idle (state '${state:-none}')" ;;
  esac
}

stop() {
  # Only the PIDs this script started; slurmd before slurmctld, munged last.
  local name pid
  for name in slurmd slurmctld munged; do
    [ -s "$STATE/$name.pid" ] || continue
    pid=$(cat "$STATE/$name.pid")
    if kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid"
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -0 "$pid" 2>/dev/null && kill -KILL "$pid"
    fi
    rm -f "$STATE/$name.pid"
  done
  # slurmctld cannot remove its own pid file after dropping privileges.
  rm -f "$STATE/slurmctld.pidfile" "$STATE/slurmd.pidfile"
  echo "slurm-local: stopped"
}

status() {
  local name ok=0
  for name in munged slurmctld slurmd; do
    if alive "$STATE/$name.pid"; then
      echo "$name: running (pid $(cat "$STATE/$name.pid"))"
    else
      echo "$name: not running"; ok=1
    fi
  done
  if [ $ok = 0 ]; then
    sinfo -N 2>&1
    squeue 2>&1
  fi
  return $ok
}

case "${1:-}" in
start) start ;;
stop) stop ;;
status) status ;;
*) die "usage: $0 start|stop|status" ;;
esac
