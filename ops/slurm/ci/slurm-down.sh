#!/usr/bin/env bash
# slurm-down.sh - stop what slurm-up.sh started, by PID file only. --purge also deletes $SLURM_CI_DIR.
set -uo pipefail
BASE=${SLURM_CI_DIR:-/tmp/sparc3d-slurm-ci}
export SLURM_CONF=$BASE/etc/slurm.conf

stop() { # stop PIDFILE COMM
  [[ -s $1 ]] || return 0
  local p; p=$(cat "$1")
  if [[ -r /proc/$p/comm && $(cat "/proc/$p/comm") == "$2" ]]; then
    kill -TERM "$p"
    for _ in $(seq 100); do [[ -d /proc/$p ]] || break; sleep 0.1; done
    [[ -d /proc/$p ]] && { echo "[slurm-down] $2 ($p) ignored TERM, sending KILL" >&2; kill -KILL "$p"; }
  fi
  rm -f "$1"
}

# cancel our jobs first so that no slurmstepd/job process outlives slurmd
if [[ -s $BASE/run/slurmctld.pid && -f $SLURM_CONF ]]; then
  scancel --quiet --user="$(id -un)" 2>/dev/null || true
  for _ in $(seq 50); do
    [[ -z $(squeue -h -t running,completing,pending 2>/dev/null) ]] && break; sleep 0.2
  done
fi
stop "$BASE/run/slurmd.pid"     slurmd
stop "$BASE/run/slurmctld.pid"  slurmctld
stop "$BASE/munge/munged.pid"   munged
[[ ${1:-} == --purge ]] && rm -rf "$BASE"
echo "[slurm-down] stopped" >&2
