#!/usr/bin/env python3
"""A job whose home is a bucket against the same job in a folder: wall time of `sparc3d run`
on each, interleaved, and the requests the bucket job made, by method and by what they touched
(counted by a proxy in front of the S3 server). Uses moto's S3 server on loopback (`pip install
'moto[server]'`), so it measures what the bucket protocol costs, not a cloud's latency.

    ops/bench/bucket_vs_local.py MESHES_DIR --resolution 512 --shard-size 4 --workers 2 \\
        --rounds 2 --work /tmp/bucket-bench

Needs `sparc3d` (SPARC3D_BIN or PATH). Prints one line per run and a summary table.
"""

import argparse
import json
import pathlib
import shutil
import subprocess
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "tests" / "python"))
from remote_servers import MotoS3, clean_env  # noqa: E402
from s3_proxy import S3Proxy  # noqa: E402

from benchlib import binary as sparc3d  # noqa: E402
from benchlib import median, timed  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("meshes", type=pathlib.Path)
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--shard-size", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--work", type=pathlib.Path, required=True)
    a = ap.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    a.work.mkdir(parents=True)
    manifest = a.work / "m.jsonl"
    subprocess.run([sparc3d(), "manifest", "build", a.meshes, "-o", manifest], check=True,
                   stderr=subprocess.DEVNULL)
    items = sum(1 for _ in manifest.open())
    s3 = MotoS3()
    s3.client.create_bucket(Bucket="bench")
    proxy = S3Proxy(s3.port)
    env = clean_env({**s3.env, "AWS_ENDPOINT_URL": proxy.endpoint,
                     "SPARC3D_SCRATCH": str(a.work / "scratch")})
    flags = ["--manifest", manifest, "--resolution", a.resolution, "--shard-size", a.shard_size]
    runs = {"folder": [], "bucket": []}
    counts = []
    try:
        for r in range(a.rounds):
            for home in ("folder", "bucket") if r % 2 == 0 else ("bucket", "folder"):
                job = a.work / f"job-{r}" if home == "folder" else f"s3://bench/job-{r}"
                subprocess.run([str(c) for c in [sparc3d(), "init", job, *flags]], check=True, env=env,
                               stderr=subprocess.DEVNULL)
                proxy.reset()
                seconds, _, _ = timed([sparc3d(), "run", job, "--workers", a.workers], env=env)
                runs[home].append(seconds)
                if home == "bucket":
                    counts.append(dict(proxy.counts))
                print(f"round {r + 1} {home}: {seconds:.1f} s", flush=True)
    finally:
        proxy.close()
        s3.close()
    f, b = median(runs["folder"]), median(runs["bucket"])
    shards = -(-items // a.shard_size)
    print(f"\n{items} items, {shards} shards, {a.resolution}³, {a.workers} workers, "
          f"{a.rounds} rounds: folder {f:.1f} s, bucket {b:.1f} s (median), bucket/folder "
          f"{b / f:.3f}")
    last = counts[-1]
    total = sum(last.values())
    print(f"requests of one bucket run: {total} ({total / items:.1f} per item, "
          f"{total / shards:.1f} per shard)")
    for (method, kind), n in sorted(last.items(), key=lambda kv: (-kv[1], kv[0])):
        print(f"  {method:6} {kind:10} {n}")
    print(json.dumps({"folder_s": runs["folder"], "bucket_s": runs["bucket"],
                      "requests": {f"{m} {k}": n for (m, k), n in last.items()}}))


if __name__ == "__main__":
    main()
