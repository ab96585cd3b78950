#!/usr/bin/env python3
"""Plot `sparc3d bench` rows: time (or memory) against active vertices, one colour per
resolution, log-log, as a self-contained SVG. Standard library only.

Usage:
    sparc3d bench DIR --resolution 512,1024 --out rows.jsonl
    python3 ops/bench/plot.py rows.jsonl [more.jsonl | report.json ...] -o docs/perf_time.svg
    python3 ops/bench/plot.py rows.jsonl --metric rss -o docs/perf_rss.svg

Inputs are JSON Lines files of rows (`--out`) or the document `--json` prints (its `rows`).
Failed rows are left out and counted in the title.
"""

import argparse
import json
import math
import sys
from html import escape

METRICS = {
    "time": ("total_seconds", "time per mesh (s)", 1.0),
    "cpu": (None, "CPU user+sys per mesh (s)", 1.0),
    "rss": ("max_rss_bytes", "peak RSS per mesh (MB)", 1e-6),
}
COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf"]


def read_rows(path):
    """Rows of a JSON Lines file or of a `bench --json` document."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    stripped = text.lstrip()
    if stripped.startswith("{") and '"rows"' in text[:200]:
        try:
            return json.loads(text)["rows"]
        except (json.JSONDecodeError, KeyError):
            pass
    rows = []
    for n, line in enumerate(text.splitlines(), 1):
        if line.strip():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError as e:
                sys.exit(f"{path}:{n}: not JSON: {e}")
    return rows


def value(row, metric):
    key, _, scale = METRICS[metric]
    if metric == "cpu":
        v = row.get("cpu_user_seconds", 0.0) + row.get("cpu_sys_seconds", 0.0)
    else:
        v = row.get(key) or (row.get("peak_rss_bytes") if metric == "rss" else None)
    return None if v is None else v * scale


def decades(lo, hi):
    a, b = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    if a == b:
        b += 1
    return a, b


def label(exp):
    v = 10.0**exp
    if exp >= 6:
        return f"{v / 1e6:g}M"
    if exp >= 3:
        return f"{v / 1e3:g}k"
    return f"{v:g}"


def svg(points, metric, title, width=720, height=480):
    left, right, top, bottom = 70, 140, 40, 55
    pw, ph = width - left - right, height - top - bottom
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    xa, xb = decades(min(xs), max(xs))
    ya, yb = decades(min(ys), max(ys))

    def px(x):
        return left + (math.log10(x) - xa) / (xb - xa) * pw

    def py(y):
        return top + ph - (math.log10(y) - ya) / (yb - ya) * ph

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="12">',
        f'<rect width="{width}" height="{height}" fill="white"/>',
        f'<text x="{left + pw / 2}" y="22" text-anchor="middle" font-size="14">'
        f"{escape(title)}</text>",
    ]
    for e in range(xa, xb + 1):
        x = px(10.0**e)
        out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{top + ph}" stroke="#ddd"/>')
        out.append(
            f'<text x="{x:.1f}" y="{top + ph + 18}" text-anchor="middle">{label(e)}</text>'
        )
    for e in range(ya, yb + 1):
        y = py(10.0**e)
        out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{left + pw}" y2="{y:.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end">{10.0**e:g}</text>')
    out.append(
        f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>'
    )
    out.append(
        f'<text x="{left + pw / 2}" y="{height - 14}" text-anchor="middle">'
        "active vertices (log)</text>"
    )
    out.append(
        f'<text transform="translate(18 {top + ph / 2}) rotate(-90)" text-anchor="middle">'
        f"{escape(METRICS[metric][1])} (log)</text>"
    )
    resolutions = sorted({p[2] for p in points})
    for i, res in enumerate(resolutions):
        colour = COLOURS[i % len(COLOURS)]
        for x, y, r, name in points:
            if r == res:
                out.append(
                    f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="3" fill="{colour}" '
                    f'fill-opacity="0.7"><title>{escape(name)}: {x} active vertices, '
                    f"{y:.3g}</title></circle>"
                )
        ly = top + 10 + 20 * i
        out.append(f'<circle cx="{left + pw + 20}" cy="{ly}" r="5" fill="{colour}"/>')
        n = sum(1 for p in points if p[2] == res)
        out.append(f'<text x="{left + pw + 32}" y="{ly + 4}">{res}³ ({n})</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("inputs", nargs="+", help="rows (.jsonl) or bench --json reports")
    ap.add_argument("-o", "--output", required=True, help="output .svg")
    ap.add_argument("--metric", choices=sorted(METRICS), default="time")
    ap.add_argument("--title", default=None)
    args = ap.parse_args()

    rows = [r for path in args.inputs for r in read_rows(path)]
    points, failed = [], 0
    for r in rows:
        v = value(r, args.metric)
        if not r.get("ok") or not r.get("active_vertices") or not v or v <= 0:
            failed += 1
            continue
        name = r.get("path", "").rsplit("/", 1)[-1]
        points.append((r["active_vertices"], v, r.get("resolution", 0), name))
    if not points:
        sys.exit("no converted rows to plot")
    title = args.title or f"sparc3d bench: {METRICS[args.metric][1]} vs active vertices"
    if failed:
        title += f" ({failed} failed rows left out)"
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(svg(points, args.metric, title))
    print(f"{len(points)} points written to {args.output}", file=sys.stderr)


if __name__ == "__main__":
    main()
