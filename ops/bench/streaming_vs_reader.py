#!/usr/bin/env python3
"""`StreamingDataset` against the plain reader over the same shards: items per second of

  plain     `iter_items(job)`: every item in file order, one process
  stream    `StreamingDataset(job)`: every item shuffled (row groups, then a 256-item buffer)
  plain-dl  `DataLoader(SparseCubesDataset(job), shuffle=True, num_workers=W)`: shuffled by
            index, what training used before (each item a read of its row group, cached)
  stream-dl `StreamingDataset(job).loader(num_workers=W)`

each timed from opening the dataset to its last item, rounds interleaved (the order turned
every round), medians and the ratios stream/plain reported. Shards are verified once before
the rounds and read with `verify=False` in them, so the figures are reading, not hashing.

    ops/bench/streaming_vs_reader.py --work /tmp/stream-bench --items 240 --resolution 128
    ops/bench/streaming_vs_reader.py --job JOB --rounds 5

Without `--job`, converts the meshes of `--meshes` (default: examples/) over and over into
`--items` items with `sparc3d` (SPARC3D_BIN or PATH). Needs torch and sparc3d_reader.
"""

import argparse
import json
import pathlib
import shutil
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "python"))
import sparc3d_reader as reader  # noqa: E402
import torch.utils.data  # noqa: E402

from benchlib import binary as sparc3d  # noqa: E402
from benchlib import median  # noqa: E402


def make_job(a):
    """`--items` items cycling over the meshes of `--meshes`, converted in `--work/job`."""
    shutil.rmtree(a.work, ignore_errors=True)
    a.work.mkdir(parents=True)
    meshes = sorted(p for p in a.meshes.iterdir() if p.suffix.lower() in
                    (".obj", ".off", ".ply", ".stl", ".glb", ".gltf"))
    manifest = a.work / "m.jsonl"
    manifest.write_text("".join(
        json.dumps({"id": f"item{i:06d}", "uri": str(meshes[i % len(meshes)])}) + "\n"
        for i in range(a.items)))
    job = a.work / "job"
    run = lambda *args: subprocess.run([sparc3d(), *map(str, args)], check=True,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    run("init", job, "--manifest", manifest, "--resolution", a.resolution,
        "--shard-size", a.shard_size)
    run("run", job, "--workers", a.workers)
    return job


def count(items):
    n = 0
    for _ in items:
        n += 1
    return n


def batches(loader):
    return sum(len(b) for b in loader)


def readers(job, workers):
    """Name → a function reading every item once, returning how many."""
    plain_dl = lambda: batches(torch.utils.data.DataLoader(
        reader.SparseCubesDataset(job, verify=False), batch_size=8, shuffle=True,
        num_workers=workers, collate_fn=list))
    stream_dl = lambda: batches(reader.StreamingDataset(job, verify=False).loader(
        batch_size=8, num_workers=workers, collate_fn=list))
    return {
        "plain": lambda: count(reader.iter_items(job, verify=False)),
        "stream": lambda: count(reader.StreamingDataset(job, verify=False)),
        "plain-dl": plain_dl,
        "stream-dl": stream_dl,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--job", type=pathlib.Path)
    ap.add_argument("--work", type=pathlib.Path, default=pathlib.Path("/tmp/stream-bench"))
    ap.add_argument("--meshes", type=pathlib.Path, default=ROOT / "examples")
    ap.add_argument("--items", type=int, default=240)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--shard-size", type=int, default=32)
    ap.add_argument("--workers", type=int, default=2, help="conversion and DataLoader workers")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    job = a.job or make_job(a)
    n = count(reader.iter_items(job))  # verified once: the rounds read without hashing
    funcs = readers(job, a.workers)
    seconds = {name: [] for name in funcs}
    for r in range(a.rounds):
        names = list(funcs) if r % 2 == 0 else list(reversed(funcs))
        for name in names:
            t = time.perf_counter()
            got = funcs[name]()
            seconds[name].append(time.perf_counter() - t)
            assert got == n, (name, got, n)
        print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in seconds.items()),
              flush=True)
    rate = {k: n / median(v) for k, v in seconds.items()}
    print(f"\n{n} items, {len(reader.shard_paths(job))} shards, {a.rounds} rounds (medians):")
    for k, v in rate.items():
        print(f"  {k:9} {v:8.1f} items/s")
    print(f"stream / plain {rate['stream'] / rate['plain']:.2f}, "
          f"stream-dl / plain-dl {rate['stream-dl'] / rate['plain-dl']:.2f}")
    print(json.dumps({"items": n, "seconds": seconds}))


if __name__ == "__main__":
    main()
