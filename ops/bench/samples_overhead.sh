#!/usr/bin/env bash
# The cost of vector-set samples and the size of every export layout, on a folder of meshes:
# two jobs on the same manifest, without and with [samples] (250k surface + 250k near + 250k
# volume points by default, sharp and sharp-near off, near offsets σ 0.005 and 0.05 as the
# figures of docs/PERFORMANCE.md were measured), run one after the other; then `sparc3d export` in each
# format. Prints wall seconds per job, their ratio, and bytes per item per layout.
#
#   ops/bench/samples_overhead.sh MESH_DIR OUT_DIR [RESOLUTION] [WORKERS]
#
# FORMATS="vecset-npz trellis2" exports only those layouts (default: all four).
set -euo pipefail
meshes=$1 out=$2 res=${3:-512} workers=${4:-2}
bin=$(python3 "$(dirname "$0")/benchlib.py" binary)
mkdir -p "$out"
"$bin" manifest build "$meshes" -o "$out/manifest.csv" >/dev/null
cat > "$out/samples.toml" <<TOML
[samples]
enabled = true
surface = ${SURFACE:-250000}
sharp = ${SHARP:-0}
near = ${NEAR:-250000}
near_sigmas = ${NEAR_SIGMAS:-[0.005, 0.05]}
sharp_near = ${SHARP_NEAR:-0}
volume = ${VOLUME:-250000}
dtype = "${DTYPE:-f16}"
TOML
rm -rf "$out/plain" "$out/samples"
"$bin" init "$out/plain" --manifest "$out/manifest.csv" --resolution "$res" >/dev/null
"$bin" init "$out/samples" --manifest "$out/manifest.csv" --resolution "$res" \
  --config "$out/samples.toml" >/dev/null
declare -A secs
for job in plain samples; do
  start=$(date +%s.%N)
  "$bin" run "$out/$job" --workers "$workers" >/dev/null 2>&1
  secs[$job]=$(echo "$(date +%s.%N) - $start" | bc)
done
items=$("$bin" status "$out/samples" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["ok"])' 2>/dev/null || echo "?")
echo "resolution $res, workers $workers, ok items $items"
echo "without samples: ${secs[plain]} s; with samples: ${secs[samples]} s; ratio $(echo "scale=3; ${secs[samples]} / ${secs[plain]}" | bc)"
for fmt in ${FORMATS:-vecset-npz direct3d-s2 trellis2 cubvh}; do
  "$bin" export "$out/samples" --format "$fmt" --out "$out/export-$fmt" >/dev/null 2>&1
  n=$(ls "$out/export-$fmt" | wc -l)
  bytes=$(du -sb "$out/export-$fmt" | cut -f1)
  echo "$fmt: $n files, $((bytes / (n > 0 ? n : 1))) bytes per item"
done
for job in plain samples; do
  echo "$job shard bytes per ok item: $(( $(du -cb "$out/$job"/shards/*.parquet | tail -1 | cut -f1) / ${items:-1} ))"
done
