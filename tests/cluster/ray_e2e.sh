#!/usr/bin/env bash
# ray_e2e.sh - end-to-end test of the Ray driver (ops/ray/) on a private Ray on loopback.
#
# Converts the 22 real meshes of tests/data/cluster as Ray tasks, one per shard, and checks:
#   1. ops/ray/run-local.sh (a head on 127.0.0.1, stopped by its PID) with a sparc3d that fails
#      one shard once (Ray retries the task: the shard completes) and another shard every time
#      (the driver exits non-zero and names it);
#   2. the driver without --address (Ray inside the driver) picks up only the shard left over;
#   3. on a finished job the driver has nothing to do and starts no Ray;
#   4. every item is present exactly once, with per-shard and job content digests equal to a
#      local `sparc3d run` of the same manifest;
#   5. a job whose home is a bucket (moto's S3 server on loopback): the driver takes its URL,
#      and the bucket job's content digest equals the local run's.
# About a minute on 2 cores after the build (each Ray start takes 5-10 s).
#
# Needs `ray`, `moto_server` and `python3` (with ray and boto3) on PATH: ./test.sh puts its virtual environment first.
# Environment: SPARC3D_BIN (default: build with cargo), RAY_E2E_DIR (scratch folder, default a
# fresh /tmp/sparc3d-ray-e2e.XXXX, removed on success), RAY_E2E_RESOLUTION (default 64).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
T0=$(date +%s)
log() { echo "[ray-e2e +$(($(date +%s) - T0))s] $*" >&2; }
fail() { log "FAIL: $*"; exit 1; }

command -v ray >/dev/null || fail "no 'ray' on PATH (pip install ray; ./test.sh installs it in .venv)"
python3 -c 'import ray' 2>/dev/null || fail "python3 ($(command -v python3)) cannot import ray"

# One token for every Ray of this test (run-local.sh's head, the driver's own Ray): token
# authentication as Ray does by default, without reading or writing ~/.ray/auth_token.
export RAY_AUTH_MODE=token
RAY_AUTH_TOKEN=$(python3 -c 'import secrets; print(secrets.token_hex(32))')
export RAY_AUTH_TOKEN

WORK=${RAY_E2E_DIR:-$(mktemp -d /tmp/sparc3d-ray-e2e.XXXXXX)}
mkdir -p "$WORK"
RES=${RAY_E2E_RESOLUTION:-64}
cleanup() {
  local rc=$?
  if [[ $rc -ne 0 ]]; then
    log "failed (rc=$rc); driver logs follow"
    for f in "$WORK"/driver-*.log; do [[ -f $f ]] && { echo "--- $f (tail)"; tail -n 20 "$f"; }; done
  fi
  [[ -n ${MOTO_PID:-} ]] && kill "$MOTO_PID" 2>/dev/null
  if [[ $rc -eq 0 && -z ${RAY_E2E_KEEP:-} ]]; then rm -rf "$WORK"; else log "kept $WORK"; fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# shellcheck source=tests/cluster/lib.sh
source "$ROOT/tests/cluster/lib.sh"
copy_binary

# A sparc3d that fails shard 3 once and shard 5 always; anything else goes to the real one.
cat >"$WORK/bin/flaky-sparc3d" <<EOF
#!/usr/bin/env bash
shard=""
prev=""
for a in "\$@"; do [[ \$prev == --shard-index ]] && shard=\$a; prev=\$a; done
if [[ \$shard == 3 && ! -e "$WORK/shard3-failed-once" ]]; then
  touch "$WORK/shard3-failed-once"; echo "injected failure of shard 3" >&2; exit 1
fi
[[ \$shard == 5 ]] && { echo "injected failure of shard 5" >&2; exit 3; }
exec "$S" "\$@"
EOF
chmod +x "$WORK/bin/flaky-sparc3d"

reference_and_job
[[ $SHARDS -gt 5 ]] || fail "$SHARDS shards: the test injects failures into shards 3 and 5"
complete() { [[ -f $WORK/job/shards/part-$(printf %05d "$1").complete.json ]]; }
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# 1. a loopback head through run-local.sh; one retried shard, one failed shard
log "run-local.sh: head on 127.0.0.1, shard 3 fails once, shard 5 always"
rc=0
RAY_PORT=$(free_port) "$ROOT/ops/ray/run-local.sh" "$WORK/job" --sparc3d "$WORK/bin/flaky-sparc3d" \
  --retries 1 >"$WORK/driver-1.log" 2>&1 || rc=$?
[[ $rc -ne 0 ]] || fail "the driver exited 0 although shard 5 failed every time"
grep -q "shards ok, 1 failed \[5\]" "$WORK/driver-1.log" || fail "the driver did not report shard 5 as failed"
[[ -e $WORK/shard3-failed-once ]] || fail "shard 3's injected failure never happened"
complete 3 || fail "shard 3 failed once and was not retried to completion"
! complete 5 || fail "shard 5 is complete although its every attempt failed"
for ((i = 0; i < SHARDS; i++)); do
  [[ $i -eq 5 ]] || complete "$i" || fail "shard $i not complete after the first run"
done

# 2. the driver's own private Ray (no --address): only the unfinished shard
log "driver with its own Ray: the shard left over"
python3 "$ROOT/ops/ray/sparc3d_ray.py" "$WORK/job" --sparc3d "$S" --local-cpus 2 \
  >"$WORK/driver-2.log" 2>&1 || fail "second driver run"
grep -q ": 1 unfinished shards" "$WORK/driver-2.log" || fail "the second run did not see exactly 1 unfinished shard"
grep -q "done: 1 shards ok, 0 failed" "$WORK/driver-2.log" || fail "the second run did not finish shard 5"

# 3. nothing left: no Ray started, exit 0
python3 "$ROOT/ops/ray/sparc3d_ray.py" "$WORK/job" --sparc3d "$S" >"$WORK/driver-3.log" 2>&1 ||
  fail "driver on a finished job"
grep -q ": 0 unfinished shards" "$WORK/driver-3.log" || fail "a finished job still had unfinished shards"

# 4. every item once, same content as the local run
same_as_reference ray-e2e

# 5. a job whose home is a bucket: the nodes share nothing but the bucket
command -v moto_server >/dev/null || fail "no 'moto_server' on PATH (pip install 'moto[server]')"
MOTO_PORT=$(free_port)
moto_server -H 127.0.0.1 -p "$MOTO_PORT" >"$WORK/moto.log" 2>&1 &
MOTO_PID=$!
export AWS_ENDPOINT_URL=http://127.0.0.1:$MOTO_PORT AWS_ACCESS_KEY_ID=testing \
  AWS_SECRET_ACCESS_KEY=testing AWS_REGION=us-east-1 SPARC3D_SCRATCH=$WORK/scratch
python3 - <<'PY' || fail "moto's S3 server did not start"
import os, time, boto3
c = boto3.client("s3", endpoint_url=os.environ["AWS_ENDPOINT_URL"])
for _ in range(300):
    try:
        c.create_bucket(Bucket="ray-e2e")
        break
    except Exception:
        time.sleep(0.1)
else:
    raise SystemExit("no bucket")
PY
log "a job in a bucket through the driver"
"$S" init s3://ray-e2e/job --manifest "$WORK/manifest.jsonl" --resolution "$RES" --shard-size 2 \
  >/dev/null 2>&1 || fail "init s3://ray-e2e/job"
python3 "$ROOT/ops/ray/sparc3d_ray.py" s3://ray-e2e/job --sparc3d "$S" --local-cpus 2 \
  >"$WORK/driver-5.log" 2>&1 || fail "driver on the bucket job"
grep -q "done: $SHARDS shards ok, 0 failed" "$WORK/driver-5.log" || fail "the bucket job's shards did not all finish"
a=$("$S" inspect "$WORK/ref" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["content_digest"])')
b=$("$S" inspect s3://ray-e2e/job --json 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["content_digest"])')
[[ -n $a && $a == "$b" ]] || fail "bucket job: content digest $b, local run $a"
log "OK: retried task, failed shard reported, resumed; $SHARDS shards equal to the local run; the bucket job too"
