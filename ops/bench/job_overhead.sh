#!/usr/bin/env bash
# Orchestrator overhead and throughput on a folder of meshes:
#   overhead = (wall × workers − Σ per-item conversion seconds) / Σ per-item conversion seconds
# where an item's conversion seconds are load + convert + extract + encode, measured inside
# its isolated worker. Also prints the throughput in meshes per hour, in total and per core
# (the machine's cores, whatever the number of workers).
# Usage: bench_overhead.sh MESH_DIR [RESOLUTION=256] [WORKERS=1] [SHARD_SIZE=16]
set -euo pipefail
DIR=$1; RES=${2:-256}; WORKERS=${3:-1}; SHARD=${4:-16}
BIN=$(python3 "$(dirname "$0")/benchlib.py" binary)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$BIN" manifest build "$DIR" -o "$WORK/m.jsonl" 2>/dev/null
"$BIN" init "$WORK/job" --manifest "$WORK/m.jsonl" --resolution "$RES" --shard-size "$SHARD" 2>/dev/null
START=$(date +%s.%N)
"$BIN" run "$WORK/job" --workers "$WORKERS" --log-interval 60s 2>/dev/null || true
END=$(date +%s.%N)
"$BIN" inspect "$WORK/job" --json > "$WORK/inspect.json"
python3 - "$WORK/inspect.json" "$START" "$END" "$WORKERS" "$RES" "$(nproc)" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
start, end, workers, res = float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
cores = int(sys.argv[6])
wall = end - start
t = r["time_sums"]
work = t["time_load_s"] + t["time_convert_s"] + t["time_extract_s"] + t["time_encode_s"]
overhead = (wall * workers - work) / work
print(f"resolution {res}, {workers} workers: {r['rows']} items ({r['ok']} ok, {r['failed']} failed)")
print(f"wall {wall:.1f} s, sum of per-item conversion {work:.1f} s, "
      f"sum of supervised item time {t['time_total_s']:.1f} s")
print(f"orchestrator overhead {100 * overhead:.2f} %")
per_hour = r['rows'] / wall * 3600
print(f"throughput {per_hour:.0f} meshes/hour, {per_hour / cores:.0f} meshes/hour/core ({cores} cores)")
PY
