#!/usr/bin/env python3
"""`sparc3d convert` of two binaries side by side, mesh by mesh (docs/PERFORMANCE.md).

For every mesh of LIST (a text file, one path a line), runs `BIN convert MESH -o OUT.ply
--resolution N --json` under `/usr/bin/time -v` for binary A and binary B, alternating which
goes first from one mesh to the next, so that load from other processes falls on both alike.
One JSON line per run goes to OUT.jsonl: wall, user and system seconds and peak RSS from
`time -v`, and the summary `convert` prints (stage seconds, faces, watertight).
`--summarize OUT.jsonl` prints median / p95 / max of wall, CPU/wall and peak RSS per binary,
the B/A ratios of the medians and of the per-mesh walls, and the stages' medians.

    python3 ops/bench/convert_ab.py LIST --a OLD_BIN --b NEW_BIN --resolution 1024 --out ab
    python3 ops/bench/convert_ab.py --summarize ab.jsonl

Only the standard library.
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile


def run_one(binary, mesh, resolution, tmp):
    """One `convert` under `time -v`: a dict of its figures, or of its failure."""
    out = os.path.join(tmp, "out.ply")
    cmd = ["/usr/bin/time", "-v", binary, "convert", mesh, "-o", out,
           "--resolution", str(resolution), "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    row = {"mesh": mesh, "bin": binary, "resolution": resolution, "rc": p.returncode}
    for key, pattern in [("wall_s", r"Elapsed \(wall clock\) time.*: (.+)"),
                         ("user_s", r"User time \(seconds\): (.+)"),
                         ("sys_s", r"System time \(seconds\): (.+)"),
                         ("rss_kb", r"Maximum resident set size \(kbytes\): (.+)")]:
        m = re.search(pattern, p.stderr)
        if m:
            row[key] = parse_time(m.group(1)) if key == "wall_s" else float(m.group(1))
    try:
        row["summary"] = json.loads(p.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        row["stderr"] = p.stderr[-500:]
    if os.path.exists(out):
        os.remove(out)
    return row


def parse_time(text):
    """Seconds from `time -v`'s `h:mm:ss` or `m:ss.ss`."""
    parts = [float(x) for x in text.strip().split(":")]
    seconds = 0.0
    for x in parts:
        seconds = seconds * 60 + x
    return seconds


def pct(values, q):
    """The q-quantile (nearest rank) of values."""
    s = sorted(values)
    return s[min(len(s) - 1, max(0, round(q * (len(s) - 1))))]


def summarize(path):
    rows = [json.loads(line) for line in open(path)]
    by = {}
    for r in rows:
        if r.get("rc") == 0 and "wall_s" in r:
            by.setdefault((r["resolution"], r["label"]), {})[r["mesh"]] = r
    for res in sorted({k[0] for k in by}):
        a, b = by.get((res, "A"), {}), by.get((res, "B"), {})
        both = sorted(set(a) & set(b))
        print(f"## {res}³, {len(both)} meshes converted by both")
        print("| binary | wall median | p95 | max | CPU/wall (summed) | RSS MB median | max |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        stats = {}
        for label, side in (("A", a), ("B", b)):
            w = [side[m]["wall_s"] for m in both]
            cpu = [side[m]["user_s"] + side[m]["sys_s"] for m in both]
            rss = [side[m]["rss_kb"] / 1024 for m in both]
            stats[label] = (statistics.median(w), pct(w, 0.95), max(w), sum(cpu) / sum(w),
                            statistics.median(rss), max(rss))
            s = stats[label]
            print(f"| {label} | {s[0]:.2f} | {s[1]:.2f} | {s[2]:.2f} | {s[3]:.2f} | "
                  f"{s[4]:.0f} | {s[5]:.0f} |")
        ratios = [b[m]["wall_s"] / a[m]["wall_s"] for m in both]
        names = ["wall median", "p95", "max", "CPU/wall", "RSS median", "RSS max"]
        print("B/A: " + ", ".join(f"{n} {stats['B'][i] / stats['A'][i]:.2f}"
                                  for i, n in enumerate(names)))
        print(f"per-mesh wall B/A: median {statistics.median(ratios):.2f}, "
              f"min {min(ratios):.2f}, max {max(ratios):.2f}")
        cpu = [(b[m]["user_s"] + b[m]["sys_s"]) / (a[m]["user_s"] + a[m]["sys_s"]) for m in both]
        print(f"per-mesh CPU (user+sys) B/A: median {statistics.median(cpu):.2f}, "
              f"min {min(cpu):.2f}, max {max(cpu):.2f}")
        for label, side in (("A", a), ("B", b)):
            stages = {}
            outside = []
            for m in both:
                st = side[m].get("summary", {}).get("stage_seconds", {})
                for k, v in st.items():
                    stages.setdefault(k, []).append(v)
                outside.append(side[m]["wall_s"] - sum(st.values()))
            parts = ", ".join(f"{k} {statistics.median(v):.3f}" for k, v in stages.items())
            print(f"{label} stage medians (s): {parts}; outside the stages "
                  f"{statistics.median(outside):.3f}")
        diff = [m for m in both
                if a[m]["summary"].get("output_faces") != b[m]["summary"].get("output_faces")]
        print(f"meshes whose output face count differs: {len(diff)} {diff[:5]}")
        print()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("list", nargs="?")
    ap.add_argument("--a")
    ap.add_argument("--b")
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--out")
    ap.add_argument("--summarize")
    args = ap.parse_args()
    if args.summarize:
        summarize(args.summarize)
        return
    if not (args.list and args.a and args.b and args.out):
        ap.error("LIST, --a, --b and --out are needed")
    meshes = [line.strip() for line in open(args.list) if line.strip()]
    with tempfile.TemporaryDirectory() as tmp, open(args.out + ".jsonl", "a") as out:
        for i, mesh in enumerate(meshes):
            order = [("A", args.a), ("B", args.b)]
            if i % 2:
                order.reverse()
            for label, binary in order:
                row = run_one(binary, mesh, args.resolution, tmp)
                row["label"] = label
                out.write(json.dumps(row) + "\n")
                out.flush()
                print(f"{i + 1}/{len(meshes)} {label} {row.get('wall_s')} s "
                      f"{os.path.basename(mesh)}", file=sys.stderr)


if __name__ == "__main__":
    main()
