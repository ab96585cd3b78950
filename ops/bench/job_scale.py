#!/usr/bin/env python3
"""What each command of a job costs as the job grows (docs/PERFORMANCE.md, "Jobs of ten
million items"). Standard library only.

    ops/bench/job_scale.py [--bin target/release/sparc3d] [--rows 1000,1000000,10000000]
        [--add 1000000] [--shard-size 256] [--work-dir DIR] [--bucket-rows 1000,1000000]
        [--json FILE] [--record]

For each N: a synthetic manifest of N rows `id,uri,sha256,license` (`s3://` sources, the shape
of an Objaverse-XL listing; nothing is fetched), then, each under its own clock and with the
peak memory of its process (VmHWM, read from /proc while it runs):

- `init JOB --manifest M`;
- `status JOB`;
- `ls JOB --where "license = CC-BY"`: time to its first line on stdout, then the whole;
- `work JOB --shard-index I --events` (I = the middle shard): time to its `shard_started`
  event (the moment before its first item), peak memory until then, then it is stopped;
- `add JOB M2` of `--add` new rows (when N > 1,000).

With `--bucket-rows`, the same commands (but `add`, which a bucket job refuses) on a job whose
home is a bucket of moto's S3 server on loopback (`pip install 'moto[server]'`), behind the
tests' counting proxy (tests/python/s3_proxy.py): each command's requests and the bytes of
their bodies, up and down, beside its time and memory. `ls` reads a local copy of the
finished shards and the whole frozen manifest (every slice, downloaded once).

Then `failures`, `verify`, `retry`, `report` and `submit slurm --dry-run` of the same job,
each alone (a table of their own). Prints Markdown tables; `--json FILE` keeps the rows,
`--record` keeps one line a job size under ops/bench/runs/<date>-<machine>/job_scale.jsonl.
"""

import argparse
import hashlib
import json
import os
import pathlib
import shutil
import sys
import tempfile

from benchlib import Results, add_binary_argument, add_record_argument, binary, timed


def write_manifest(path, rows, start=0):
    """N rows of id,uri,sha256,license: ids and sha256s made up, licences in four kinds."""
    licences = ["CC-BY", "CC0", "CC-BY-NC", "MIT"]
    with open(path, "w") as f:
        f.write("id,uri,sha256,license\n")
        for i in range(start, start + rows):
            sha = hashlib.sha256(str(i).encode()).hexdigest()
            f.write(f"obj{i:09d},s3://objaverse-xl/{sha[:2]}/{sha}.glb,{sha},{licences[i % 4]}\n")


# The other commands that read a whole job, each timed alone on the job before any shard is
# converted: what they cost of the job's size, not of its results.
SUMMARIES = [
    ("failures", lambda job, work: ["failures", job]),
    ("verify", lambda job, work: ["verify", job]),
    ("retry", lambda job, work: ["retry", job]),
    ("report", lambda job, work: ["report", job, "-o", work / "report"]),
    ("submit", lambda job, work: ["submit", "slurm", job, "--dry-run"]),
]


def measure(binary, rows, add, shard_size, work):
    job, m = work / f"job-{rows}", work / f"m-{rows}.csv"
    shutil.rmtree(job, ignore_errors=True)
    write_manifest(m, rows)
    out = {"rows": rows}
    out["init"] = timed([binary, "init", job, "--manifest", m, "--shard-size", shard_size])
    out["status"] = timed([binary, "status", job])
    out["ls_where"] = timed([binary, "ls", job, "--where", "license = CC-BY"])
    for name, cmd in SUMMARIES:
        out[name] = timed([binary, *cmd(job, work)])
    shards = (rows + shard_size - 1) // shard_size
    env = dict(os.environ, AWS_ACCESS_KEY_ID="x", AWS_SECRET_ACCESS_KEY="x",
               AWS_ENDPOINT_URL="http://127.0.0.1:9", AWS_ALLOW_HTTP="true")
    out["work"] = timed([binary, "work", job, "--shard-index", shards // 2, "--events"],
                        until='"shard_started"', env=env)
    if add and rows > 1000:
        m2 = work / f"add-{rows}.csv"
        write_manifest(m2, add, start=rows)
        out["add"] = timed([binary, "add", job, m2])
    m.unlink()
    return out


def measure_bucket(binary, rows, shard_size, work):
    """The commands of `measure` on a bucket job of `rows` rows: (seconds, first line, peak
    KB, requests, bytes up, bytes down) each."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests" / "python"))
    from remote_servers import MotoS3, clean_env
    from s3_proxy import S3Proxy

    m = work / f"m-{rows}.csv"
    write_manifest(m, rows)
    s3 = MotoS3()
    s3.client.create_bucket(Bucket="scale")
    proxy = S3Proxy(s3.port)
    scratch = work / f"scratch-{rows}"
    shutil.rmtree(scratch, ignore_errors=True)
    env = clean_env({**s3.env, "AWS_ENDPOINT_URL": proxy.endpoint,
                     "SPARC3D_SCRATCH": str(scratch)})
    url = f"s3://scale/job-{rows}"
    shards = (rows + shard_size - 1) // shard_size
    out = {"rows": rows}

    def step(name, cmd, until=None):
        proxy.reset()
        seconds, first, peak = timed([binary, *cmd], until=until, env=env)
        with proxy.lock:
            requests = sum(proxy.counts.values())
            out[name] = (seconds, first, peak, requests, proxy.bytes_up, proxy.bytes_down)

    try:
        step("init", ["init", url, "--manifest", m, "--shard-size", shard_size])
        step("status", ["status", url])
        step("status_again", ["status", url])
        step("work", ["work", url, "--shard-index", shards // 2, "--events"],
             until='"shard_started"')
        step("ls_where", ["ls", url, "--where", "license = CC-BY"])
    finally:
        proxy.close()
        s3.close()
        m.unlink()
    return out


def bucket_table(results):
    print("\n| rows (bucket) | command | time | peak memory | requests | bytes up, down |")
    print("|---|---|---|---|---|---|")
    names = [("init", "init"), ("status", "status"), ("status_again", "status again"),
             ("work", "work: to its first item"), ("ls_where", "ls --where (all)")]
    for r in results:
        for key, label in names:
            t, _, peak, n, up, down = r[key]
            print(f"| {r['rows']:,} | {label} | {t:.2f} s | {peak / 1024:.0f} MB | {n:,} | "
                  f"{up / 1e6:.2f} MB, {down / 1e6:.2f} MB |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_binary_argument(ap)
    add_record_argument(ap)
    ap.add_argument("--rows", default="1000,1000000")
    ap.add_argument("--add", type=int, default=1000000)
    ap.add_argument("--shard-size", type=int, default=256)
    ap.add_argument("--work-dir")
    ap.add_argument("--bucket-rows", default="")
    ap.add_argument("--json")
    a = ap.parse_args()
    a.bin = binary(a.bin)
    record = Results("job_scale", a.record, a.bin)
    work = pathlib.Path(a.work_dir or tempfile.mkdtemp(prefix="sparc3d-scale-"))
    work.mkdir(parents=True, exist_ok=True)
    results = [measure(a.bin, int(n), a.add, a.shard_size, work) for n in a.rows.split(",") if n]
    print("| rows | init | status | ls --where: first line, all | work: to its first item | add |")
    print("|---|---|---|---|---|---|")
    cell = lambda r: f"{r[0]:.2f} s, {r[2] / 1024:.0f} MB"
    for r in results:
        ls = r["ls_where"]
        add = cell(r["add"]) if "add" in r else "—"
        print(f"| {r['rows']:,} | {cell(r['init'])} | {cell(r['status'])} | "
              f"{ls[1] or 0:.2f} s, {ls[0]:.2f} s, {ls[2] / 1024:.0f} MB | {cell(r['work'])} | {add} |")
    print("\n| rows | " + " | ".join(name for name, _ in SUMMARIES) + " |")
    print("|---|" + "---|" * len(SUMMARIES))
    for r in results:
        print(f"| {r['rows']:,} | " + " | ".join(cell(r[name]) for name, _ in SUMMARIES) + " |")
    bucket = [measure_bucket(a.bin, int(n), a.shard_size, work)
              for n in a.bucket_rows.split(",") if n]
    if bucket:
        bucket_table(bucket)
    for home, rows in (("folder", results), ("bucket", bucket)):
        for r in rows:
            record.add({"home": home, "shard_size": a.shard_size, **r})
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps({"folder": results, "bucket": bucket},
                                                   indent=2))


if __name__ == "__main__":
    main()
