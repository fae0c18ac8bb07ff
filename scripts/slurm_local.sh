#!/usr/bin/env bash
# A one-node SLURM on this machine (munge + slurmctld + slurmd for `hostname -s`), to try
# `hydra/launcher=submitit_slurm` sweeps locally and to test them in CI (.ci/run).
#
#   scripts/slurm_local.sh start    install slurm-wlm + munge if missing (apt-get), write
#                                   /etc/slurm/slurm.conf, start the daemons, wait until
#                                   `sinfo` shows the node idle (exit 1 with the log's tail if not)
#   scripts/slurm_local.sh status   exit 0 when the controller answers and the node is idle
#   scripts/slurm_local.sh stop     stop the daemons this script started (by their pid files)
#
# Idempotent: `start` on a running SLURM only checks it. Needs root (the daemons run as
# root: SlurmUser=root). Accounting is off (accounting_storage/none): there is no sacct;
# decrun reads job states from squeue/scontrol instead (decrun/runner/sweep/launchers/slurm.py).
# KillWait=5: `scancel` sends SIGTERM, then SIGKILL 5 s later.
set -euo pipefail

CONF=/etc/slurm/slurm.conf
MARK="# written by decrun scripts/slurm_local.sh"
LOGDIR=/var/log/slurm
SPOOL=/var/spool
RUN=/run/slurm
TIMEOUT=${SLURM_LOCAL_TIMEOUT:-60}

die() { echo "slurm_local: error: $*" >&2; exit 1; }

as_root() {
  [ "$(id -u)" -eq 0 ] || die "needs root (the daemons run as root); run it with sudo"
}

install_packages() {
  if command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null \
     && command -v sinfo >/dev/null; then
    return
  fi
  echo "slurm_local: installing slurm-wlm and munge (apt-get)" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq || die "apt-get update failed"
  apt-get install -y -qq slurm-wlm munge >/dev/null || die "apt-get install -y slurm-wlm munge failed"
}

ensure_hostname() {
  local host
  host=$(hostname -s)
  if ! getent hosts "$host" >/dev/null; then
    echo "127.0.0.1 $host" >> /etc/hosts
    echo "slurm_local: added '127.0.0.1 $host' to /etc/hosts" >&2
  fi
}

write_conf() {
  local host node
  host=$(hostname -s)
  if [ -f "$CONF" ] && ! grep -qF "$MARK" "$CONF"; then
    die "$CONF exists and was not written by this script; move it away to use a local SLURM"
  fi
  # CPUs, sockets, cores, RealMemory of this machine, as slurmd sees them
  node=$(slurmd -C | head -n 1 | sed "s/^NodeName=[^ ]*/NodeName=$host/")
  mkdir -p /etc/slurm "$LOGDIR" "$SPOOL/slurmctld" "$SPOOL/slurmd" "$RUN"
  cat > "$CONF.tmp" <<EOF
$MARK
ClusterName=decrun-local
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
KillWait=5
MinJobAge=600
SlurmctldPidFile=$RUN/slurmctld.pid
SlurmdPidFile=$RUN/slurmd.pid
StateSaveLocation=$SPOOL/slurmctld
SlurmdSpoolDir=$SPOOL/slurmd
SlurmctldLogFile=$LOGDIR/slurmctld.log
SlurmdLogFile=$LOGDIR/slurmd.log
$node State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  mv "$CONF.tmp" "$CONF"
}

alive() {  # alive PIDFILE: the process of the pid file runs
  [ -s "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null
}

start_munge() {
  local pidfile=/run/munge/munged.pid
  mkdir -p /run/munge /var/lib/munge /var/log/munge
  chown munge:munge /run/munge /var/lib/munge /var/log/munge
  chmod 0755 /run/munge
  if [ ! -s /etc/munge/munge.key ]; then
    mungekey --create --keyfile=/etc/munge/munge.key
  fi
  chown munge:munge /etc/munge/munge.key
  chmod 0400 /etc/munge/munge.key
  if alive "$pidfile"; then
    return
  fi
  runuser -u munge -- munged --pid-file="$pidfile" || die "munged did not start (see /var/log/munge/munged.log)"
}

start_daemon() {  # start_daemon NAME: slurmctld or slurmd
  local pidfile="$RUN/$1.pid"
  if alive "$pidfile"; then
    return
  fi
  "$1" || die "$1 did not start (see $LOGDIR/$1.log)"
}

node_state() {
  timeout 10 sinfo -h -N -o "%T" 2>/dev/null | head -n 1
}

wait_idle() {
  local host state="" waited=0
  host=$(hostname -s)
  while [ "$waited" -lt "$TIMEOUT" ]; do
    state=$(node_state || true)
    case "$state" in
      idle|mixed|allocated) return 0 ;;
      down*|drain*|drained*) scontrol update NodeName="$host" State=RESUME >/dev/null 2>&1 || true ;;
    esac
    sleep 1
    waited=$((waited + 1))
  done
  echo "--- $LOGDIR/slurmctld.log" >&2; tail -n 5 "$LOGDIR/slurmctld.log" >&2 || true
  echo "--- $LOGDIR/slurmd.log" >&2; tail -n 5 "$LOGDIR/slurmd.log" >&2 || true
  die "node $host is not idle after ${TIMEOUT}s (sinfo: '${state:-no answer}'); logs above"
}

stop_pidfile() {  # stop_pidfile PIDFILE NAME
  local pid i
  if alive "$1"; then
    pid=$(cat "$1")
    kill "$pid"
    for i in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -0 "$pid" 2>/dev/null && kill -9 "$pid"
    echo "slurm_local: stopped $2 ($pid)" >&2
  fi
  rm -f "$1"
}

case "${1:-}" in
  start)
    as_root
    install_packages
    ensure_hostname
    write_conf
    start_munge
    start_daemon slurmctld
    start_daemon slurmd
    wait_idle
    echo "slurm_local: node $(hostname -s) is up ($(node_state))" >&2
    ;;
  status)
    state=$(node_state || true)
    case "$state" in
      idle|mixed|allocated) echo "slurm_local: node $(hostname -s) is $state" ;;
      *) echo "slurm_local: not running (sinfo: '${state:-no answer}')" >&2; exit 1 ;;
    esac
    ;;
  stop)
    as_root
    stop_pidfile "$RUN/slurmd.pid" slurmd
    stop_pidfile "$RUN/slurmctld.pid" slurmctld
    stop_pidfile /run/munge/munged.pid munged
    ;;
  *)
    echo "usage: $0 start|status|stop" >&2
    exit 2
    ;;
esac
