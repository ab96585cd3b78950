# lib.sh - what the cluster tests (slurm_e2e.sh, ray_e2e.sh) share; sourced, not run. The caller
# sets ROOT, WORK, RES and defines log() and fail().

# copy_binary: S is a copy of the sparc3d binary (SPARC3D_BIN, else built with cargo), so that a
# rebuild while the test runs cannot change it under the scheduler.
copy_binary() {
  if [[ -z ${SPARC3D_BIN:-} ]]; then
    log "building sparc3d"
    (cd "$ROOT" && cargo build -q -p sparc3d)
    SPARC3D_BIN=${CARGO_TARGET_DIR:-$ROOT/target}/debug/sparc3d
  fi
  mkdir -p "$WORK/bin"
  cp "$SPARC3D_BIN" "$WORK/bin/sparc3d"
  S=$WORK/bin/sparc3d
}

# reference_and_job: the real meshes of tests/data/cluster as two jobs of one manifest, two items
# a shard: $WORK/ref, converted here by `sparc3d run`, and $WORK/job, left to the scheduler.
# Sets ITEMS and SHARDS.
reference_and_job() {
  "$S" manifest build "$ROOT/tests/data/cluster" -o "$WORK/manifest.jsonl" >/dev/null
  ITEMS=$(grep -c . "$WORK/manifest.jsonl")
  [[ $ITEMS -ge 20 ]] || fail "manifest has $ITEMS items, expected at least 20"
  local j
  for j in ref job; do
    "$S" init "$WORK/$j" --manifest "$WORK/manifest.jsonl" --resolution "$RES" --shard-size 2 >/dev/null
  done
  SHARDS=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["shards"])' "$WORK/job/job.json")
  log "$ITEMS meshes in $SHARDS shards at resolution $RES; local reference run"
  "$S" run "$WORK/ref" --workers 2 >/dev/null 2>"$WORK/ref-run.log" || { cat "$WORK/ref-run.log"; fail "local run"; }
}

# same_as_reference TAG: every item of $WORK/job exactly once, each shard's and the job's content
# digest equal to the local run's, no temporary shard file left.
same_as_reference() {
  local i p a b leftover
  for ((i = 0; i < SHARDS; i++)); do
    p=$(printf 'part-%05d.parquet' "$i")
    a=$("$S" inspect "$WORK/ref/shards/$p" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["content_digest"])')
    b=$("$S" inspect "$WORK/job/shards/$p" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["content_digest"])')
    [[ -n $a && $a == "$b" ]] || fail "shard $i: content digest $b, local run $a"
  done
  python3 - "$S" "$WORK" "$ITEMS" "$1" <<'PY' || fail "job-level comparison"
import json, subprocess, sys
s, work, items, tag = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
r = {j: json.loads(subprocess.check_output([s, "inspect", f"{work}/{j}", "--json"])) for j in ("ref", "job")}
assert r["job"]["rows"] == items, f'{r["job"]["rows"]} rows for {items} items'
assert r["job"]["content_digest"] == r["ref"]["content_digest"], "job digests differ"
assert (r["job"]["ok"], r["job"]["failed"]) == (r["ref"]["ok"], r["ref"]["failed"])
print(f'[{tag}] {items} rows ({r["job"]["ok"]} ok, {r["job"]["failed"]} failed), digest {r["job"]["content_digest"][:16]}', file=sys.stderr)
PY
  leftover=$(find "$WORK/job/shards" -name '.*tmp*' | wc -l)
  [[ $leftover -eq 0 ]] || fail "$leftover temporary shard files left"
}
