#!/usr/bin/env python3
"""Throughput of a whole job by worker count (docs/PERFORMANCE.md, "Every core busy").
Standard library only.

    ops/bench/job_throughput.py --meshes DIR [--bin target/release/sparc3d] \\
        [--resolution 512] [--workers 1,2,4,8,16] [--shard-size 256] [--rounds 2] \\
        [--out rows.json] [--record]

Builds one manifest of DIR, then for each round and each worker count (interleaved, so that a
noisy machine weighs on every count alike) makes a fresh job with `sparc3d init` and times
`sparc3d run JOB --workers N` alone. Prints a Markdown table of medians over the rounds: wall,
meshes per hour, the speed-up over the first worker count, CPU/wall of the whole process tree
(cores kept busy), the summed item time over the wall (items converting at once, as `run`
reports it) and the peak memory of the whole tree (the sum of its processes' RSS, sampled
every 50 ms). Every job's content digest must be the same whatever the worker count: the
script says so, or fails. --record keeps every job's row under
ops/bench/runs/<date>-<machine>/job_throughput.jsonl.
"""

import argparse
import json
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from benchlib import Results, add_binary_argument, add_record_argument, binary, fail
from benchlib import run as run_checked


def tree_rss_bytes(root_pid):
    """The summed RSS of `root_pid` and all its descendants, from /proc."""
    children = {}
    rss = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            children.setdefault(int(fields[1]), []).append(int(entry))
            rss[int(entry)] = int(fields[21]) * os.sysconf("SC_PAGE_SIZE")
        except (OSError, IndexError, ValueError):
            continue
    total, stack = 0, [root_pid]
    while stack:
        pid = stack.pop()
        total += rss.get(pid, 0)
        stack.extend(children.get(pid, []))
    return total


def timed_run(binary, job, workers):
    """`run JOB --workers N`: wall, CPU of the tree, peak tree RSS, and run's summary line."""
    t0 = time.monotonic()
    proc = subprocess.Popen([binary, "run", str(job), "--workers", str(workers),
                             "--log-interval", "1h"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    peak = 0
    while proc.poll() is None:
        peak = max(peak, tree_rss_bytes(proc.pid))
        time.sleep(0.05)
    # The process is reaped by poll(); its and its descendants' CPU from RUSAGE_CHILDREN.
    wall = time.monotonic() - t0
    err = proc.stderr.read()
    if proc.returncode != 0:
        fail(f"run --workers {workers} exited {proc.returncode}: {err.strip()[-2000:]}")
    m = re.search(r"item time ([\d.]+)s over ([\d.]+)s wall", err)
    items = re.search(r"^(\d+) items in ", err, re.M)
    return {"wall": wall, "peak_rss_bytes": peak,
            "item_seconds": float(m.group(1)) if m else float("nan"),
            "items": int(items.group(1)) if items else 0}


def one_round(binary, manifest, tmp, args, workers):
    job = tmp / f"job_w{workers}"
    shutil.rmtree(job, ignore_errors=True)
    run_checked([binary, "init", job, "--manifest", manifest, "--resolution", args.resolution,
                 "--shard-size", args.shard_size])
    before = os.times()
    row = timed_run(binary, job, workers)
    after = os.times()
    row["cpu"] = (after.children_user - before.children_user
                  + after.children_system - before.children_system)
    digest = json.loads(run_checked([binary, "inspect", job, "--json"]).stdout)
    row["digest"] = digest["content_digest"]
    row["workers"] = workers
    return row


def table(rows, counts):
    first = None
    lines = ["| workers | wall (s) | meshes/h | speed-up | CPU/wall | items at once | peak memory |",
             "|---:|---:|---:|---:|---:|---:|---:|"]
    for n in counts:
        mine = [r for r in rows if r["workers"] == n]
        wall = statistics.median(r["wall"] for r in mine)
        items = mine[0]["items"]
        first = first or wall
        lines.append(
            f"| {n} | {wall:.2f} | {items / wall * 3600:.0f} | {first / wall:.2f}× "
            f"| {statistics.median(r['cpu'] / r['wall'] for r in mine):.2f} "
            f"| {statistics.median(r['item_seconds'] / r['wall'] for r in mine):.2f} "
            f"| {max(r['peak_rss_bytes'] for r in mine) / 2**30:.2f} GiB |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_binary_argument(ap)
    add_record_argument(ap)
    ap.add_argument("--meshes", required=True, type=pathlib.Path)
    ap.add_argument("--resolution", default="512")
    ap.add_argument("--workers", default="1,2,4,8,16")
    ap.add_argument("--shard-size", default="256")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", type=pathlib.Path)
    args = ap.parse_args()
    sparc3d = binary(args.bin)
    results = Results("job_throughput", args.record, sparc3d)
    counts = [int(w) for w in args.workers.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        manifest = tmp / "manifest.jsonl"
        run_checked([sparc3d, "manifest", "build", args.meshes, "-o", manifest])
        for k in range(args.rounds):
            for n in counts:
                row = one_round(sparc3d, manifest, tmp, args, n)
                row["round"] = k
                rows.append(row)
                results.add({"resolution": args.resolution, "shard_size": args.shard_size, **row})
                print(f"round {k + 1}, {n} workers: {row['wall']:.2f} s", file=sys.stderr)
    digests = {r["digest"] for r in rows}
    if len(digests) != 1:
        fail(f"the content digest differs between worker counts: {sorted(digests)}")
    print(f"{rows[0]['items']} meshes at {args.resolution}³, shard size {args.shard_size}, "
          f"{os.cpu_count()} cores, medians of {args.rounds} rounds; "
          f"one content digest for every count ({rows[0]['digest'][:12]}…)\n")
    print(table(rows, counts))
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
