#!/usr/bin/env python3
"""Thread scaling of `sparc3d convert`: the same meshes benchmarked at 1, 2, 4, ... threads
(docs/PERFORMANCE.md, "Thread scaling"). Standard library only.

    ops/bench/thread_scaling.py --meshes DIR [--bin target/release/sparc3d] \\
        [--resolution 1024] [--threads 1,2,4,8,16] [--out rows.json] [--record]

Runs `sparc3d bench DIR --resolution R --threads T` once per thread count (each with its own
warm-up conversion) and prints a Markdown table: median wall per mesh, the speed-up of the
median over one thread, the median CPU/wall ratio (cores kept busy) and the peak RSS. --out
keeps every bench row, with its thread count, as one JSON document; --record keeps one line
a thread count under ops/bench/runs/<date>-<machine>/thread_scaling.jsonl.
"""

import argparse
import json
import pathlib
import statistics
import sys
import tempfile

from benchlib import Results, add_binary_argument, add_record_argument, binary, fail, run


def bench_rows(binary, meshes, resolution, threads):
    """Every row `sparc3d bench` wrote for one thread count."""
    with tempfile.TemporaryDirectory() as tmp:
        rows_path = pathlib.Path(tmp) / "rows.jsonl"
        cmd = [binary, "bench", str(meshes), "--resolution", str(resolution),
               "--threads", str(threads), "--timeout", "5m", "--out", str(rows_path)]
        run(cmd)
        rows = [json.loads(line) for line in rows_path.read_text().splitlines() if line.strip()]
    for row in rows:
        row["threads"] = threads
    return rows


def summary(rows):
    """Median wall, CPU/wall and peak RSS over the meshes that converted."""
    ok = [r for r in rows if r.get("ok")]
    if not ok:
        return None
    walls = [r["process_seconds"] for r in ok]
    busy = [(r["cpu_user_seconds"] + r["cpu_sys_seconds"]) / r["process_seconds"] for r in ok]
    return {"meshes": len(ok), "failed": len(rows) - len(ok),
            "median_wall": statistics.median(walls), "total_wall": sum(walls),
            "median_busy": statistics.median(busy),
            "peak_rss_mb": max(r["max_rss_bytes"] for r in ok) / 1e6}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_binary_argument(ap)
    add_record_argument(ap)
    ap.add_argument("--meshes", required=True, type=pathlib.Path)
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--threads", default="1,2,4,8,16")
    ap.add_argument("--out", type=pathlib.Path)
    args = ap.parse_args()
    sparc3d = binary(args.bin)
    try:
        counts = [int(t) for t in args.threads.split(",")]
    except ValueError:
        fail(f"--threads {args.threads!r}: expected comma-separated integers like 1,2,4")
    if not args.meshes.exists():
        fail(f"--meshes {args.meshes}: no such file or folder")
    all_rows, table = [], []
    results = Results("thread_scaling", args.record, sparc3d)
    for t in counts:
        rows = bench_rows(sparc3d, args.meshes, args.resolution, t)
        all_rows += rows
        s = summary(rows)
        if s is None:
            fail(f"no mesh converted at {t} threads")
        table.append((t, s))
        results.add({"resolution": args.resolution, "threads": t, **s})
        print(f"{t} threads: median wall {s['median_wall']:.3f} s", file=sys.stderr, flush=True)
    base = table[0][1]["median_wall"]
    print("| threads | meshes | median wall (s) | speed-up | total wall (s) | CPU/wall | peak RSS (MB) |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for t, s in table:
        print(f"| {t} | {s['meshes']} | {s['median_wall']:.3f} | {base / s['median_wall']:.2f} "
              f"| {s['total_wall']:.2f} | {s['median_busy']:.2f} | {s['peak_rss_mb']:.0f} |")
    if args.out:
        args.out.write_text(json.dumps({"resolution": args.resolution, "rows": all_rows}) + "\n")


if __name__ == "__main__":
    main()
