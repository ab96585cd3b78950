#!/usr/bin/env python3
"""The cost of `[attributes]` (issue 43's bar: the attribute stage <= 25 % of the conversion at
the median, peak memory <= 1.3x without it), on the items `attributes_reference.py --out`
measured (the dev corpus's items with appearance, rebuilt with their textures beside them in
its `--keep` folder).

Each item is converted twice in a row by the release binary, with and without
`--attributes`, each under `/usr/bin/time -v` (peak RSS: "Maximum resident set size"); the
share is the `attributes` stage of `convert --json`'s `stage_seconds` over its
`total_seconds`, both from the run with attributes. The two runs of an item are back to back,
so their memory ratio is measured on the same machine state; times on a shared machine are
noisy, so compare shares and ratios, not seconds across runs.

    cargo build --release -p sparc3d
    python3 ops/bench/attributes_cost.py ref.jsonl --resolution 512
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

from benchlib import Results, add_binary_argument, add_record_argument, binary


def convert(sparc3d, path, resolution, attributes, scratch):
    """(`convert --json` summary, peak RSS in bytes)."""
    out = os.path.join(scratch, "out.ply")
    cmd = ["/usr/bin/time", "-v", sparc3d, "convert", path, "-o", out,
           "--resolution", str(resolution), "--json"]
    if attributes:
        cmd.append("--attributes")
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        raise RuntimeError(run.stderr.strip().splitlines()[-1] if run.stderr else "failed")
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", run.stderr)
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    os.remove(out)
    return summary, int(rss.group(1)) * 1024 if rss else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("items", help="JSON lines of attributes_reference.py --out (their paths)")
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--limit", type=int, default=0, help="measure the first N items only")
    add_binary_argument(ap)
    add_record_argument(ap)
    args = ap.parse_args()
    sparc3d = binary(args.bin)
    results = Results("attributes_cost", args.record, sparc3d)
    items = [json.loads(l) for l in open(args.items) if l.strip()]
    items = [i for i in items if "error" not in i and os.path.exists(i["path"])]
    if args.limit:
        items = items[: args.limit]
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for item in items:
            try:
                plain, rss_plain = convert(sparc3d, item["path"], args.resolution, False, scratch)
                coloured, rss_coloured = convert(sparc3d, item["path"], args.resolution, True,
                                                 scratch)
            except RuntimeError as e:
                print(f"{item['item']}: {e}", file=sys.stderr)
                continue
            stage = coloured["stage_seconds"].get("attributes", 0.0)
            row = {
                "item": item["item"],
                "faces": coloured["input_faces"],
                "cells": coloured["active_cells"],
                "total_s": coloured["total_seconds"],
                "plain_total_s": plain["total_seconds"],
                "attributes_s": stage,
                "share": stage / coloured["total_seconds"],
                "rss_plain": rss_plain,
                "rss_coloured": rss_coloured,
                "rss_ratio": rss_coloured / max(rss_plain, 1),
            }
            rows.append(row)
            results.add({"resolution": args.resolution, **row})
            print(json.dumps(row), file=sys.stderr)
    print("| item | input faces | active cells | convert s (with / without) | attributes s | "
          "share | peak RSS MiB (with / without) | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    mib = 1 << 20
    for r in rows:
        print(f"| `{r['item']}` | {r['faces']} | {r['cells']} | {r['total_s']:.2f} / "
              f"{r['plain_total_s']:.2f} | {r['attributes_s']:.2f} | {100 * r['share']:.1f} % | "
              f"{r['rss_coloured'] / mib:.0f} / {r['rss_plain'] / mib:.0f} | "
              f"{r['rss_ratio']:.2f} |")
    if rows:
        shares = [r["share"] for r in rows]
        ratios = [r["rss_ratio"] for r in rows]
        print(f"\n{len(rows)} items at {args.resolution}³: attribute stage share median "
              f"{100 * statistics.median(shares):.1f} % (max {100 * max(shares):.1f} %); "
              f"peak RSS ratio median {statistics.median(ratios):.2f} (max {max(ratios):.2f})")


if __name__ == "__main__":
    main()
