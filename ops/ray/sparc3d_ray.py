#!/usr/bin/env python3
"""Run a sparc3d job on a Ray cluster: one Ray task per unfinished shard, each running
`sparc3d work JOB --shard-index I` as a subprocess, retried when it fails or its node dies.

    python3 ops/ray/sparc3d_ray.py /shared/jobs/objaverse --address 127.0.0.1:6379
    python3 ops/ray/sparc3d_ray.py JOB                   # no --address: a private local Ray

The job folder and the sparc3d binary must be at the same path on every Ray node; or JOB is
the bucket prefix that is the job's home (s3://, gs://, az://: docs/CLUSTER.md, "Jobs in a
bucket"), and the nodes need only the binary and the bucket's credentials. Without
--address, Ray starts inside this process on 127.0.0.1 only (RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0
makes Ray honour the loopback node address) and stops with it. `ray stop` kills every Ray
process on the host: stop a head you started by its PID instead (see run-local.sh).
"""
import argparse
import json
import os
import subprocess
import sys
import time

os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")


def is_url(job):
    return "://" in job


def unfinished_shards(job, sparc3d):
    """Shards without a completion record (`work` re-checks each one before skipping it). For
    a job in a bucket, every shard: `sparc3d status` gives the count, and a task whose shard is
    done ends after one read of its record."""
    if is_url(job):
        r = subprocess.run([sparc3d, "status", job, "--json"], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"{job}: {r.stderr.strip()}")
        status = json.loads(r.stdout)
        return list(range(int(status["shards"]))) if status["shards_done"] < status["shards"] else []
    with open(os.path.join(job, "job.json")) as f:
        shards = int(json.load(f)["shards"])
    done = os.path.join(job, "shards", "part-{:05d}.complete.json")
    return [i for i in range(shards) if not os.path.exists(done.format(i))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("job", help="job folder (sparc3d init) on storage every node mounts, or the "
                    "bucket prefix that is the job's home")
    ap.add_argument("--address", default=os.environ.get("RAY_ADDRESS"),
                    help="Ray cluster to join (default: a private local one on 127.0.0.1)")
    ap.add_argument("--sparc3d", default="sparc3d", help="the sparc3d binary on the nodes")
    ap.add_argument("--num-cpus", type=float, default=1, help="CPUs reserved per shard task")
    ap.add_argument("--memory-gb", type=float, default=0, help="memory reserved per task (GB)")
    ap.add_argument("--retries", type=int, default=3, help="retries of a failed shard task")
    ap.add_argument("--local-cpus", type=int, default=None, help="CPUs of the private local Ray")
    ap.add_argument("work_args", nargs="*", help="more `sparc3d work` arguments (after --)")
    a = ap.parse_args()

    import ray  # imported late so that --help works without Ray installed

    job = a.job if is_url(a.job) else os.path.abspath(a.job)
    todo = unfinished_shards(job, a.sparc3d)
    print(f"{job}: {len(todo)} unfinished shards", file=sys.stderr)
    if not todo:
        return 0
    if a.address:
        ray.init(address=a.address, logging_level="ERROR")
    else:
        # Ray's raylet gives its agents 15 s to report their ports and aborts past that, which
        # a busy machine can miss: up to three tries.
        for attempt in range(1, 4):
            try:
                ray.init(num_cpus=a.local_cpus, include_dashboard=False,
                         _node_ip_address="127.0.0.1", logging_level="ERROR")
                break
            except Exception as e:  # Ray raises a bare Exception for a node that did not start
                ray.shutdown()
                if attempt == 3:
                    raise
                print(f"Ray did not start (try {attempt} of 3): {e}", file=sys.stderr)

    @ray.remote(max_retries=a.retries, retry_exceptions=True)
    def work(shard):
        cmd = [a.sparc3d, "work", job, "--shard-index", str(shard), *a.work_args]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"shard {shard}: exit {r.returncode}: {r.stderr.strip()[-2000:]}")
        return shard, r.stderr.strip().splitlines()[-1:] or [""]

    opts = {"num_cpus": a.num_cpus}
    if a.memory_gb > 0:
        opts["memory"] = int(a.memory_gb * 1e9)
    pending = {work.options(**opts).remote(s): s for s in todo}
    failed, t0 = [], time.time()
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            shard = pending.pop(ref)
            try:
                _, last = ray.get(ref)
                print(f"[{time.time() - t0:7.1f}s] {last[0]}", file=sys.stderr)
            except Exception as e:  # the task failed after its retries
                failed.append(shard)
                print(f"[{time.time() - t0:7.1f}s] shard {shard} failed: {e}", file=sys.stderr)
    ray.shutdown()
    print(f"done: {len(todo) - len(failed)} shards ok, {len(failed)} failed {failed}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
