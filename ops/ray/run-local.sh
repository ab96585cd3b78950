#!/usr/bin/env bash
# run-local.sh JOB [driver args...] - start a private Ray head on 127.0.0.1, run the sparc3d
# driver against it, and stop the head by its PID (never `ray stop`: it kills every Ray process
# on the host). Needs `pip install ray` (about 300 MB; no dashboard, so no extras) and sparc3d on
# PATH or --sparc3d. RAY_PORT picks the head's port (default 6390).
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
D=$(mktemp -d /tmp/sparc3d-ray.XXXXXX)
export RAY_USAGE_STATS_ENABLED=0
export RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0    # else --node-ip-address=127.0.0.1 is ignored
# Token authentication with a token of this run (unless one is given): no other local user can
# submit work to this head, and a token that another Ray left in ~/.ray cannot get in the way
# (Ray 2.60 turns authentication on for a head that finds one, but not for the driver).
export RAY_AUTH_MODE=token
RAY_AUTH_TOKEN=${RAY_AUTH_TOKEN:-$(python3 -c 'import secrets; print(secrets.token_hex(32))')}
export RAY_AUTH_TOKEN
PORT=${RAY_PORT:-6390}
# --block keeps the launcher in the foreground; SIGTERM to it tears down the head's processes.
# Ray's raylet gives its agents 15 s to report their ports and aborts past that, which a busy
# machine can miss (seen at a load of 10 on 2 cores): up to three tries.
HEAD=""
trap '[[ -n $HEAD ]] && { kill -TERM $HEAD 2>/dev/null; wait $HEAD 2>/dev/null; }; rm -rf "$D"' EXIT
for try in 1 2 3; do
  ray start --head --port="$PORT" --node-ip-address=127.0.0.1 --include-dashboard=false \
    --temp-dir="$D/tmp$try" --disable-usage-stats --block >"$D/head.log" 2>&1 &
  HEAD=$!
  until grep -q "Ray runtime started" "$D/head.log" || ! kill -0 $HEAD 2>/dev/null; do sleep 0.2; done
  grep -q "Ray runtime started" "$D/head.log" && break
  wait $HEAD 2>/dev/null || true
  HEAD=""
  echo "run-local.sh: the Ray head did not start (try $try of 3):" >&2
  tail -n 3 "$D/head.log" >&2
done
[[ -n $HEAD ]] || exit 1
python3 "$HERE/sparc3d_ray.py" --address "127.0.0.1:$PORT" "$@"
