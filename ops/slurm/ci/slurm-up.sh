#!/usr/bin/env bash
# slurm-up.sh - idempotently bring up a private single-node Slurm cluster on loopback (for CI and
# for trying `sparc3d submit slurm` on one machine). No systemd needed: daemons are started by hand.
# Everything (config, keys, sockets, state, logs, pid files) lives under $SLURM_CI_DIR.
# Usage: sudo ./slurm-up.sh ; then: source "$SLURM_CI_DIR/env.sh"
set -euo pipefail

BASE=${SLURM_CI_DIR:-/tmp/sparc3d-slurm-ci}
CTLD_PORT=${SLURM_CI_CTLD_PORT:-16817}   # non-default ports: never collide with a host Slurm
SLURMD_PORT=${SLURM_CI_SLURMD_PORT:-16818}
CPUS=${SLURM_CI_CPUS:-$(nproc)}
CONF=$BASE/etc/slurm.conf
MSOCK=$BASE/munge/munge.sock

log() { echo "[slurm-up] $*" >&2; }
alive() { # alive PIDFILE COMM -> 0 if the pid in PIDFILE is running and is COMM
  [[ -s $1 ]] || return 1
  local p; p=$(cat "$1")
  [[ -r /proc/$p/comm && $(cat "/proc/$p/comm") == "$2" ]]
}

[[ $(id -u) -eq 0 ]] || { log "must run as root (SlurmUser=root, munged key ownership)"; exit 1; }

# 1. packages (no recommends: 8 debs, ~3.5 MB download, ~13 MB installed)
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
   ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
  log "installing slurmctld slurmd slurm-client munge"
  export DEBIAN_FRONTEND=noninteractive
  apt_get() { apt-get -q -o DPkg::Lock::Timeout=300 "$@" >/dev/null; }
  apt_get install -y --no-install-recommends slurmctld slurmd slurm-client munge ||
    { apt_get update && apt_get install -y --no-install-recommends slurmctld slurmd slurm-client munge; }
fi

# 2. directories
mkdir -p "$BASE"/{etc,spool/ctld,spool/d,log,run,munge,jobs}
chmod 755 "$BASE" "$BASE/munge"   # munged: socket dir must be world-executable

# 3. munge (own key + socket, does not touch /etc/munge or /run/munge)
if [[ ! -s $BASE/munge/munge.key ]]; then
  mungekey --create --keyfile="$BASE/munge/munge.key" --force
fi
chmod 600 "$BASE/munge/munge.key"
if ! alive "$BASE/munge/munged.pid" munged; then
  rm -f "$BASE/munge/munged.pid" "$MSOCK" "$MSOCK.lock"
  munged --socket="$MSOCK" --key-file="$BASE/munge/munge.key" \
         --pid-file="$BASE/munge/munged.pid" --log-file="$BASE/munge/munged.log" \
         --seed-file="$BASE/munge/munged.seed"
  for _ in $(seq 50); do [[ -S $MSOCK ]] && break; sleep 0.1; done
fi
munge -S "$MSOCK" -n | unmunge -S "$MSOCK" >/dev/null || { log "munge self-test failed"; cat "$BASE/munge/munged.log" >&2; exit 1; }

# 4. slurm.conf (rewritten each time; identical content => harmless)
cat > "$CONF" <<EOF
ClusterName=ci
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
# cred_expire also = delay before a requeued job may restart (default 120 s)
AuthInfo=socket=$MSOCK,cred_expire=10
StateSaveLocation=$BASE/spool/ctld
SlurmdSpoolDir=$BASE/spool/d
SlurmctldPidFile=$BASE/run/slurmctld.pid
SlurmdPidFile=$BASE/run/slurmd.pid
SlurmctldLogFile=$BASE/log/slurmctld.log
SlurmdLogFile=$BASE/log/slurmd.log
# no cgroups, no accounting daemon
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$BASE/log/jobcomp.log
MpiDefault=none
# bind daemons to the loopback address only instead of 0.0.0.0
CommunicationParameters=NoCtldInAddrAny,NoInAddrAny
SchedulerType=sched/backfill
# schedule immediately on submit; backfill every 1 s (picks up requeued/eligible jobs fast)
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0,bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
MinJobAge=600
KillWait=5
Waittime=0
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$CPUS State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$CONF
echo "export SLURM_CONF=$CONF" > "$BASE/env.sh"

# 5. daemons (both daemonize and write their pid files)
if ! alive "$BASE/run/slurmctld.pid" slurmctld; then
  rm -f "$BASE/run/slurmctld.pid"
  slurmctld -f "$CONF"
fi
if ! alive "$BASE/run/slurmd.pid" slurmd; then
  rm -f "$BASE/run/slurmd.pid"
  slurmd -f "$CONF" -N localhost      # hostname is not "localhost": force the node name
fi

# 6. wait until the node is schedulable
for _ in $(seq 150); do
  state=$(sinfo -h -n localhost -o %T 2>/dev/null || true)
  [[ $state == idle || $state == mixed || $state == allocated ]] && { log "up: node $state; source $BASE/env.sh"; exit 0; }
  sleep 0.2
done
log "node not ready (state='${state:-?}')"; tail -n 30 "$BASE"/log/slurm*.log >&2; exit 1
