#!/usr/bin/env bash
# A job whose items are fetched over HTTP against the same job on local files: the folder's
# meshes served by Python's http.server on loopback, two manifests with the same rows (ids and
# sha256 from `manifest build`, so `init` fetches nothing), one with paths, one with URLs.
# Each round makes both jobs afresh and times `sparc3d run`, alternating which goes first;
# prints every run, the medians and their ratio (HTTP / local), and checks both jobs converted
# the same number of items.
#
#   ops/bench/remote_vs_local.sh MESH_DIR OUT_DIR [ROUNDS] [RESOLUTION] [WORKERS]
set -euo pipefail
meshes=$(realpath "$1") out=$2 rounds=${3:-3} res=${4:-512} workers=${5:-2}
bin=$(python3 "$(dirname "$0")/benchlib.py" binary)
mkdir -p "$out"
"$bin" manifest build "$meshes" -o "$out/local.csv" >/dev/null 2>&1
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
python3 -m http.server "$port" --bind 127.0.0.1 --directory "$meshes" >/dev/null 2>&1 &
server=$!
trap 'kill $server' EXIT
python3 - "$out/local.csv" "$out/http.csv" "$meshes" "http://127.0.0.1:$port" <<'PY'
import csv, sys, urllib.parse
src, dst, root, base = sys.argv[1:]
rows = list(csv.DictReader(open(src)))
with open(dst, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    for r in rows:
        r["uri"] = base + "/" + urllib.parse.quote(r["uri"][len(root):].lstrip("/"))
        w.writerow(r)
PY
sleep 1
declare -A runs ok
for ((r = 1; r <= rounds; r++)); do
  order=(local http)
  ((r % 2 == 0)) && order=(http local)
  for v in "${order[@]}"; do
    rm -rf "$out/job_$v"
    "$bin" init "$out/job_$v" --manifest "$out/$v.csv" --resolution "$res" >/dev/null 2>&1
    start=$(date +%s.%N)
    "$bin" run "$out/job_$v" --workers "$workers" >/dev/null 2>&1 || true
    s=$(echo "$(date +%s.%N) - $start" | bc)
    runs[$v]+="$s "
    ok[$v]=$("$bin" status "$out/job_$v" --json | python3 -c 'import json, sys; print(json.load(sys.stdin)["ok"])')
    echo "round $r $v: $s s, ${ok[$v]} ok"
  done
done
median() { tr ' ' '\n' | grep -v '^$' | sort -g | awk '{a[NR]=$1} END {print (NR%2) ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2}'; }
ml=$(echo "${runs[local]}" | median) mh=$(echo "${runs[http]}" | median)
echo "resolution $res, workers $workers, $rounds rounds; ok items: local ${ok[local]}, http ${ok[http]}"
echo "median local $ml s, median http $mh s, ratio $(echo "scale=4; $mh / $ml" | bc)"
[[ ${ok[local]} == "${ok[http]}" ]]
