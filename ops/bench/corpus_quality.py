#!/usr/bin/env python3
"""Quality of `sparc3d convert` over a folder of meshes (docs/QUALITY.md, "How we measure").

For every mesh in CORPUS (OBJ, PLY, STL, OFF, glTF, GLB), converts it at one resolution with
and without deformation, measures each output against the source with `sparc3d eval`, and
writes one JSON line per mesh to OUT.jsonl plus a summary (printed, and in OUT.summary.json):
medians of cd×N, point-to-surface cd×N, anc and F1, components kept, offset on closed
sources, watertight outputs as reported by `convert --json`, and how often deformation beats
no deformation mesh by mesh.

    python3 ops/bench/corpus_quality.py CORPUS --resolution 256 --out /tmp/quality
    python3 ops/bench/corpus_quality.py --summarize /tmp/quality.jsonl

Only the standard library. Run from the repository root after
`cargo build --release -p sparc3d`, or pass --bin.
"""

import argparse
import concurrent.futures
import json
import os
import statistics
import sys
import tempfile

from benchlib import MESH_EXTENSIONS, add_binary_argument, binary, last_json

MODES = {"deform": ["--deform"], "no_deform": ["--no-deform"]}


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("corpus", nargs="?", help="folder of meshes")
    p.add_argument("--resolution", type=int, default=256)
    p.add_argument("--samples", type=int, default=100_000)
    p.add_argument("--out", default="corpus_quality", help="output prefix: PREFIX.jsonl, PREFIX.summary.json")
    add_binary_argument(p)
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per command")
    p.add_argument("--jobs", type=int, default=1, help="meshes measured at once")
    p.add_argument("--limit", type=int, default=0, help="only the first K meshes (0: all)")
    p.add_argument("--resume", action="store_true", help="skip meshes already in PREFIX.jsonl")
    p.add_argument("--summarize", metavar="JSONL", help="only summarise an existing results file")
    args = p.parse_args()
    if not args.summarize:
        args.bin = binary(args.bin)
    return args


def find_key(obj, key):
    """The first value under `key` anywhere in nested dicts/lists, or None."""
    if isinstance(obj, dict):
        if key in obj:
            return obj[key]
        values = obj.values()
    elif isinstance(obj, list):
        values = obj
    else:
        return None
    for v in values:
        found = find_key(v, key)
        if found is not None:
            return found
    return None


def measure(args, mesh, workdir):
    """Converts and evaluates one mesh in both modes; returns its JSON record."""
    os.makedirs(workdir, exist_ok=True)
    record = {"mesh": os.path.basename(mesh), "resolution": args.resolution}
    for mode, flags in MODES.items():
        out = os.path.join(workdir, f"{mode}.ply")
        convert, t_convert, err = last_json(
            [args.bin, "convert", mesh, "-o", out, "--resolution", str(args.resolution), "--json", *flags],
            args.timeout,
            json_optional=True,
        )
        entry = {"convert_seconds": round(t_convert, 3)}
        if err:
            entry["error"] = f"convert: {err}"
            record[mode] = entry
            continue
        entry["convert"] = convert
        report, t_eval, err = last_json(
            [args.bin, "eval", mesh, out, "--resolution", str(args.resolution), "--samples", str(args.samples), "--json"],
            args.timeout,
        )
        entry["eval_seconds"] = round(t_eval, 3)
        if err:
            entry["error"] = f"eval: {err}"
        else:
            entry["eval"] = report
        record[mode] = entry
        if os.path.exists(out):
            os.remove(out)
    return record


def rounded_median(values):
    values = [v for v in values if v is not None]
    return round(statistics.median(values), 4) if values else None


def summarize(records, resolution):
    """Per-mode medians and counts, plus the per-mesh comparison deform vs no deform."""
    summary = {"meshes": len(records), "resolution": resolution}
    for mode in MODES:
        entries = [r.get(mode, {}) for r in records]
        ok = [e["eval"] for e in entries if "eval" in e]
        watertight = [find_key(e.get("convert"), "watertight") for e in entries if "convert" in e]
        manifold = [find_key(e.get("convert"), "manifold") for e in entries if "convert" in e]
        # Closed after welding, measured by eval itself (every edge shared by two triangles).
        output_closed = [r.get("output_closed") for r in ok]
        closed = [r for r in ok if r.get("source_closed")]
        summary[mode] = {
            "evaluated": len(ok),
            "failed": len(entries) - len(ok),
            "median_cd_voxels": rounded_median(r["cd_voxels"] for r in ok),
            "median_cd_floor_voxels": rounded_median(r["cd_floor"] * r["options"]["resolution"] for r in ok),
            "median_cd_surface_voxels": rounded_median(r["cd_surface"] * r["options"]["resolution"] for r in ok),
            "median_anc": rounded_median(r["anc"] for r in ok),
            "median_f1": {str(f["threshold"]): rounded_median(x["f1"][i]["f1"] for x in ok) for i, f in enumerate(ok[0]["f1"])} if ok else {},
            "components_kept": sum(r["components_kept"] for r in ok),
            "components_total": sum(r["components_total"] for r in ok),
            "meshes_all_components_kept": sum(r["components_kept"] == r["components_total"] for r in ok),
            "closed_sources": len(closed),
            "median_offset_voxels_closed": rounded_median(r["offset_voxels"] for r in closed),
            "watertight_outputs": sum(w is True for w in watertight),
            "watertight_reported": sum(w is not None for w in watertight),
            "manifold_outputs": sum(m is True for m in manifold),
            "closed_outputs_by_eval": sum(c is True for c in output_closed),
            "median_convert_seconds": rounded_median(e.get("convert_seconds") for e in entries if "convert" in e),
        }
    pairs = [(r["deform"]["eval"], r["no_deform"]["eval"]) for r in records
             if "eval" in r.get("deform", {}) and "eval" in r.get("no_deform", {})]
    summary["paired"] = {
        "meshes": len(pairs),
        "deform_better_cd_surface": sum(d["cd_surface"] < n["cd_surface"] for d, n in pairs),
        "deform_better_cd": sum(d["cd"] < n["cd"] for d, n in pairs),
        "deform_better_anc": sum(d["anc"] > n["anc"] for d, n in pairs),
        "median_cd_surface_ratio": rounded_median(d["cd_surface"] / n["cd_surface"] for d, n in pairs if n["cd_surface"] > 0),
    }
    return summary


def print_summary(s):
    print(f"\n{s['meshes']} meshes at N={s['resolution']}")
    rows = [
        ("evaluated / failed", lambda m: f"{m['evaluated']} / {m['failed']}"),
        ("median cd×N (voxels)", lambda m: m["median_cd_voxels"]),
        ("  sampling floor ×N", lambda m: m["median_cd_floor_voxels"]),
        ("median point-to-surface cd×N", lambda m: m["median_cd_surface_voxels"]),
        ("median anc", lambda m: m["median_anc"]),
        *[(f"median F1@{t}", (lambda t: lambda m: m["median_f1"].get(t))(t)) for t in ("0.002", "0.005", "0.01")],
        ("components kept / total", lambda m: f"{m['components_kept']} / {m['components_total']}"),
        ("meshes with all kept", lambda m: m["meshes_all_components_kept"]),
        ("closed sources; median offset", lambda m: f"{m['closed_sources']}; {m['median_offset_voxels_closed']}"),
        ("watertight outputs (reported)", lambda m: f"{m['watertight_outputs']} ({m['watertight_reported']})"),
        ("manifold outputs", lambda m: m["manifold_outputs"]),
        ("closed outputs (eval's check)", lambda m: m["closed_outputs_by_eval"]),
        ("median convert seconds", lambda m: m["median_convert_seconds"]),
    ]
    print(f"{'':32}{'deform':>18}{'no deform':>18}")
    for name, get in rows:
        print(f"{name:32}{str(get(s['deform'])):>18}{str(get(s['no_deform'])):>18}")
    p = s["paired"]
    print(f"deform better (of {p['meshes']}): cd_surface {p['deform_better_cd_surface']}, "
          f"cd {p['deform_better_cd']}, anc {p['deform_better_anc']}; "
          f"median cd_surface ratio {p['median_cd_surface_ratio']}")


def main():
    args = parse_args()
    if args.summarize:
        with open(args.summarize) as f:
            records = [json.loads(l) for l in f if l.strip()]
        resolution = records[0]["resolution"] if records else args.resolution
        print_summary(summarize(records, resolution))
        return 0
    if not args.corpus:
        sys.exit("usage: corpus_quality.py CORPUS [--resolution N] [--out PREFIX]")
    meshes = sorted(
        os.path.join(args.corpus, f) for f in os.listdir(args.corpus)
        if os.path.splitext(f)[1].lower() in MESH_EXTENSIONS
    )
    if args.limit:
        meshes = meshes[: args.limit]
    jsonl = args.out + ".jsonl"
    done = {}
    if args.resume and os.path.exists(jsonl):
        with open(jsonl) as f:
            done = {r["mesh"]: r for r in map(json.loads, filter(str.strip, f))}
    records = [done[os.path.basename(m)] for m in meshes if os.path.basename(m) in done]
    todo = [m for m in meshes if os.path.basename(m) not in done]
    with open(jsonl, "a" if args.resume else "w") as out, tempfile.TemporaryDirectory() as workdir, \
            concurrent.futures.ThreadPoolExecutor(max(1, args.jobs)) as pool:
        futures = {
            pool.submit(measure, args, m, os.path.join(workdir, str(i))): m for i, m in enumerate(todo)
        }
        for i, future in enumerate(concurrent.futures.as_completed(futures), 1):
            record = future.result()
            records.append(record)
            out.write(json.dumps(record) + "\n")
            out.flush()
            d, n = record["deform"], record["no_deform"]
            cell = lambda e: f"cd×N {e['eval']['cd_voxels']:.3f} anc {e['eval']['anc']:.2f}" if "eval" in e else e.get("error", "?")[:60]
            print(f"[{i}/{len(todo)}] {record['mesh']}: deform {cell(d)} | no deform {cell(n)}", file=sys.stderr, flush=True)
    summary = summarize(records, args.resolution)
    with open(args.out + ".summary.json", "w") as f:
        json.dump(summary, f, indent=2)
    print_summary(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
