#!/usr/bin/env bash
# run-local.sh JOB [driver args...] - start a private Ray head on 127.0.0.1, run the sparc3d
# driver against it, and stop the head by its PID (never `ray stop`: it kills every Ray process
# on the host). Needs `pip install "ray[default]"` (about 300 MB) and sparc3d on PATH or --sparc3d.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
D=$(mktemp -d /tmp/sparc3d-ray.XXXXXX)
export RAY_USAGE_STATS_ENABLED=0
export RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0    # else --node-ip-address=127.0.0.1 is ignored
PORT=${RAY_PORT:-6390}
# --block keeps the launcher in the foreground; SIGTERM to it tears down the head's processes
ray start --head --port="$PORT" --node-ip-address=127.0.0.1 --include-dashboard=false \
  --temp-dir="$D/tmp" --disable-usage-stats --block >"$D/head.log" 2>&1 &
HEAD=$!
trap 'kill -TERM $HEAD 2>/dev/null; wait $HEAD 2>/dev/null; rm -rf "$D"' EXIT
until grep -q "Ray runtime started" "$D/head.log"; do
  kill -0 $HEAD 2>/dev/null || { cat "$D/head.log"; exit 1; }
  sleep 0.2
done
python3 "$HERE/sparc3d_ray.py" --address "127.0.0.1:$PORT" "$@"
