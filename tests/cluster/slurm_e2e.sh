#!/usr/bin/env bash
# slurm_e2e.sh - end-to-end test of `sparc3d submit slurm` on a real single-node Slurm.
#
# Brings up slurmctld, slurmd and munged on 127.0.0.1 (ops/slurm/ci/slurm-up.sh; installs
# Debian's packages if missing, so it needs root and apt), converts the 22 real meshes of
# tests/data/cluster as an array job, cancels a running task and pending tasks while the
# array runs, resubmits with `sparc3d submit slurm` (only the unfinished shards), and checks
# that every item is present exactly once with per-shard content digests equal to a local
# `sparc3d run` of the same manifest. Every daemon it started is stopped by PID on exit, even
# on failure. About 1-3 minutes on 2 cores after the build.
#
# Environment: SPARC3D_BIN (default: build with cargo), SLURM_E2E_DIR (scratch folder,
# default a fresh /tmp/sparc3d-slurm-e2e.XXXX), SLURM_E2E_RESOLUTION (default 64),
# SLURM_CI_CTLD_PORT / SLURM_CI_SLURMD_PORT (default: two free ports).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
T0=$(date +%s)
log() { echo "[slurm-e2e +$(($(date +%s) - T0))s] $*" >&2; }
fail() { log "FAIL: $*"; exit 1; }

WORK=${SLURM_E2E_DIR:-$(mktemp -d /tmp/sparc3d-slurm-e2e.XXXXXX)}
mkdir -p "$WORK"
chmod 755 "$WORK"
# a private Slurm for this run: its config, keys, sockets, logs and pid files live here
export SLURM_CI_DIR=$WORK/slurm
# and ports of its own, free now, so that two runs on one machine do not collide
read -r port1 port2 < <(python3 -c 'import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*(x.getsockname()[1] for x in s))')
export SLURM_CI_CTLD_PORT=${SLURM_CI_CTLD_PORT:-$port1} SLURM_CI_SLURMD_PORT=${SLURM_CI_SLURMD_PORT:-$port2}
RES=${SLURM_E2E_RESOLUTION:-64}

cleanup() {
  local rc=$?
  if [[ $rc -ne 0 ]]; then
    log "failed (rc=$rc); logs follow"
    for f in "$SLURM_CI_DIR"/log/slurmctld.log "$SLURM_CI_DIR"/log/slurmd.log; do
      [[ -f $f ]] && { echo "--- $f (tail)"; tail -n 20 "$f"; }
    done
    for f in "$WORK"/job/slurm/logs/*.out; do
      [[ -f $f ]] && { echo "--- $f (tail)"; tail -n 5 "$f"; }
    done
  fi
  "$ROOT/ops/slurm/ci/slurm-down.sh" || true
  if [[ $rc -eq 0 && -z ${SLURM_E2E_KEEP:-} ]]; then rm -rf "$WORK"; else log "kept $WORK"; fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# shellcheck source=tests/cluster/lib.sh
source "$ROOT/tests/cluster/lib.sh"
# 1. the binary
copy_binary

# 2. Slurm on loopback
log "starting Slurm under $SLURM_CI_DIR"
SLURM_CI_CPUS=${SLURM_CI_CPUS:-$(nproc)} "$ROOT/ops/slurm/ci/slurm-up.sh"
# shellcheck disable=SC1091
source "$SLURM_CI_DIR/env.sh"

# 3. two jobs with one manifest: a local reference and the Slurm one
reference_and_job

# wait until none of the given array jobs has a task in the queue (sbatch --wait backs off)
wait_gone() {
  local deadline=$(($(date +%s) + ${2:-300}))
  while [[ -n $(squeue -h -j "$1" 2>/dev/null) ]]; do
    [[ $(date +%s) -lt $deadline ]] || fail "jobs $1 still queued after ${2:-300}s"
    sleep 0.3
  done
}
complete_shards() { ls "$WORK"/job/shards/*.complete.json 2>/dev/null | wc -l; }

# 4. submit, then cancel one running task and three pending ones while the array runs
log "submit slurm (2 tasks at a time)"
JID1=$("$S" submit slurm "$WORK/job" --max-concurrent 2)
[[ $JID1 =~ ^[0-9]+$ ]] || fail "submit printed '$JID1', not one job id"
deadline=$(($(date +%s) + 120))
until squeue -h -j "$JID1" -t RUNNING -o '%K' | grep -q .; do
  [[ $(date +%s) -lt $deadline ]] || fail "no task of $JID1 started"
  sleep 0.1
done
RUNNING_TASK=$(squeue -h -j "$JID1" -t RUNNING -o '%K' | head -n1)
PENDING_TASKS=$(squeue -h -r -j "$JID1" -t PENDING -o '%K' | sort -n | tail -n 3 | paste -sd' ')
[[ -n $PENDING_TASKS ]] || fail "no pending tasks to cancel"
log "cancelling running task $RUNNING_TASK and pending tasks $PENDING_TASKS of $JID1"
targets=("${JID1}_$RUNNING_TASK")
for t in $PENDING_TASKS; do targets+=("${JID1}_$t"); done
scancel "${targets[@]}"
"$S" status "$WORK/job" | sed 's/^/  status: /' >&2
wait_gone "$JID1"
DONE1=$(complete_shards)
log "first array left the queue with $DONE1 of $SHARDS shards complete"
[[ $DONE1 -lt $SHARDS ]] || fail "cancelling left no shard unfinished"
for t in $PENDING_TASKS; do
  [[ ! -f $WORK/job/shards/part-$(printf %05d "$t").complete.json ]] || fail "cancelled pending task $t ran"
done

# 5. resubmit: only the unfinished shards
log "resubmitting"
JID2=$("$S" submit slurm "$WORK/job" --max-concurrent 2 2>"$WORK/submit2.err") || { cat "$WORK/submit2.err" >&2; fail "resubmit"; }
cat "$WORK/submit2.err" >&2
[[ $JID2 =~ ^[0-9]+$ ]] || fail "resubmit printed '$JID2', not one job id"
TASKS2=$(scontrol -o show job "$JID2" | grep -c 'ArrayTaskId=' || true)
ARRAY2=$(tail -n1 "$WORK/job/slurm/submissions.jsonl")
log "second array $JID2: $ARRAY2"
python3 - "$ARRAY2" "$((SHARDS - DONE1))" <<'EOF' || fail "resubmission does not cover exactly the unfinished shards"
import json, sys
sub, want = json.loads(sys.argv[1]), int(sys.argv[2])
assert sub["tasks"] == want, (sub, want)
EOF
wait_gone "$JID2"
"$S" status "$WORK/job" | sed 's/^/  status: /' >&2
# Capture first: `grep -q` stops reading at the match, and the rest of the output would then
# hit a closed pipe (SIGPIPE), which pipefail reports as a failure.
STATUS_TEXT=$("$S" status "$WORK/job")
grep -q "^slurm:  2 array(s) submitted; 0 task(s) pending, 0 running" <<<"$STATUS_TEXT" ||
  fail "status does not show the two arrays"
[[ $(complete_shards) -eq $SHARDS ]] || fail "$(complete_shards) of $SHARDS shards complete after resubmission"
JID3=$("$S" submit slurm "$WORK/job" 2>/dev/null)
[[ -z $JID3 ]] || fail "a finished job was submitted again ($JID3)"

# 6. every item exactly once, same content as the local run
same_as_reference slurm-e2e
[[ -n $(ls "$WORK"/job/slurm/logs/"${JID2}"_*.out 2>/dev/null) ]] || fail "no per-task logs"
log "OK: array, cancel, resubmit; $SHARDS shards equal to the local run"
