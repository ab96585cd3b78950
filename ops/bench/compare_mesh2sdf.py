#!/usr/bin/env python3
"""sparc3d against the common pipeline (mesh2sdf), mesh by mesh (docs/QUALITY.md).

The common pipeline used to make training meshes watertight (Dora, CLAY, Craftsman follow the
mesh2sdf README example): normalise the mesh into [-1, 1] with a margin (`--mesh-scale`, 0.8
in the README), compute an unsigned distance grid of SIZE³, extract the level set at one voxel
(`level = 2/SIZE`) with marching cubes, keep the largest component, map back to the source
frame. That is exactly `mesh2sdf.compute(vertices, faces, SIZE, fix=True, level=2/SIZE,
return_mesh=True)`, whose steps this script calls one by one so that the time to the mesh is
measured apart from `compute`'s final recompute of the distance grid (`--with-resdf` adds it).

For every mesh of CORPUS (a folder, smallest file first, or a text file with one path a line,
in its order):

1. load it with trimesh (`force="mesh"`, no processing) and write it as `source.ply`, so both
   pipelines see the very same triangles;
2. run the common pipeline on it (in a subprocess with a time limit; a time-out is recorded);
3. run `sparc3d convert source.ply --resolution SIZE`;
4. measure both outputs against `source.ply` with `sparc3d eval --resolution SIZE --json`.

One JSON line per mesh goes to OUT.jsonl (a rerun skips meshes already there), and a
side-by-side table is printed (and written to OUT.md): cd×N, point-to-surface cd×N, anc,
F1@0.005, components kept, offset on closed sources, watertight output, time.

    python3 -m venv /tmp/m2s && /tmp/m2s/bin/pip install mesh2sdf scikit-image trimesh
    cargo build --release -p sparc3d
    /tmp/m2s/bin/python ops/bench/compare_mesh2sdf.py DEV_CORPUS --size 256 \\
        --out /tmp/m2s_dev --timeout 300
    python3 ops/bench/compare_mesh2sdf.py --summarize /tmp/m2s_dev.jsonl

mesh2sdf is single-threaded and slow (minutes per mesh at 256); not run in CI.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from benchlib import MESH_EXTENSIONS, add_binary_argument, binary, last_json, median

F1_THRESHOLD = 0.005


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("corpus", nargs="?", help="folder of meshes, or a file listing one path a line")
    p.add_argument("--size", type=int, default=256, help="grid resolution of both pipelines")
    p.add_argument("--mesh-scale", type=float, default=0.8, help="mesh2sdf margin (README: 0.8)")
    p.add_argument("--out", default="compare_mesh2sdf", help="output prefix: PREFIX.jsonl, PREFIX.md")
    add_binary_argument(p)
    p.add_argument("--timeout", type=float, default=300.0, help="seconds per mesh and pipeline")
    p.add_argument("--samples", type=int, default=100_000, help="points sampled by eval")
    p.add_argument("--limit", type=int, default=0, help="stop after this many meshes (0: all)")
    p.add_argument("--with-resdf", action="store_true",
                   help="also time mesh2sdf's final recompute of the distance grid (doubles its time)")
    p.add_argument("--summarize", metavar="JSONL", help="only print the table of an earlier run")
    # Internal: one common-pipeline conversion, run in a child process so it can be timed out.
    p.add_argument("--mesh2sdf-one", nargs=2, metavar=("SOURCE_PLY", "OUT_PLY"), help=argparse.SUPPRESS)
    return p.parse_args(argv)


def mesh2sdf_one(source, out, size, mesh_scale, resdf):
    """The common pipeline on one mesh; prints its time to the watertight mesh.

    These are the steps of `mesh2sdf.compute(v, f, size, fix=True, level=2/size,
    return_mesh=True)` (mesh2sdf 1.1.0, mesh2sdf/compute.py), called one by one through the
    package's own functions so the mesh is exactly the one `compute` returns: the grid distance
    (`mesh2sdf.core.compute`), marching cubes of its absolute value at `level`
    (scikit-image), the component with the largest bounding box (trimesh `split`). `compute`
    then recomputes the distance grid of that mesh, which does not change the mesh and costs
    as much again; it is timed only with `--with-resdf` (as `resdf_seconds`).
    """
    import mesh2sdf.core  # noqa: imported here so --summarize needs only the standard library
    import numpy as np
    import skimage.measure
    import trimesh

    mesh = trimesh.load(source, force="mesh", process=False)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces)
    bbmin, bbmax = vertices.min(0), vertices.max(0)
    center = (bbmin + bbmax) * 0.5
    scale = 2.0 * mesh_scale / (bbmax - bbmin).max()
    t0 = time.perf_counter()
    sdf = mesh2sdf.core.compute((vertices - center) * scale, faces, size)
    mc_vertices, mc_faces, _, _ = skimage.measure.marching_cubes(np.abs(sdf), 2.0 / size)
    parts = trimesh.Trimesh(mc_vertices, mc_faces).split(only_watertight=False)
    extents = [(p.vertices.max(0) - p.vertices.min(0)).max() for p in parts]
    fixed = parts[int(np.argmax(extents))]
    fixed.vertices = fixed.vertices * (2.0 / size) - 1.0
    seconds = time.perf_counter() - t0
    record = {"seconds": seconds, "faces": int(len(fixed.faces))}
    if resdf:
        t1 = time.perf_counter()
        mesh2sdf.core.compute(fixed.vertices, fixed.faces, size)
        record["resdf_seconds"] = time.perf_counter() - t1
    fixed.vertices = fixed.vertices / scale + center
    fixed.export(out)
    print(json.dumps(record))


def list_meshes(corpus):
    """A folder's meshes smallest file first, or a list file's meshes in its order."""
    if os.path.isdir(corpus):
        paths = [os.path.join(corpus, n) for n in os.listdir(corpus)]
        paths.sort(key=lambda p: (os.path.getsize(p), p))
    else:
        with open(corpus) as f:
            paths = [line.strip() for line in f if line.strip() and not line.startswith("#")]
    return [p for p in paths if os.path.splitext(p)[1].lower() in MESH_EXTENSIONS and os.path.isfile(p)]


def export_source(path, dest):
    """Loads a mesh with trimesh and writes its triangles as PLY; returns the face count."""
    import numpy as np
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=False)
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))))
    if len(faces) == 0:
        raise ValueError("no triangles")
    trimesh.Trimesh(mesh.vertices, faces, process=False).export(dest)
    return int(len(faces))


def run_json(cmd, timeout):
    """Runs a command that prints one JSON object last; returns (object, seconds) or raises."""
    info, seconds, err = last_json(cmd, timeout)
    if err:
        raise RuntimeError(err)
    return info, seconds


def evaluate(args, source, output):
    cmd = [args.bin, "eval", source, output, "--resolution", str(args.size), "--samples", str(args.samples), "--json"]
    report, _ = run_json(cmd, args.timeout)
    return report


def measure(args, path, work):
    """Both pipelines on one mesh; returns the JSON record."""
    rec = {"mesh": os.path.basename(path), "bytes": os.path.getsize(path), "size": args.size}
    source = os.path.join(work, "source.ply")
    try:
        rec["source_faces"] = export_source(path, source)
    except Exception as e:  # a mesh trimesh cannot read is recorded, not fatal
        rec["error"] = "load: %s" % e
        return rec
    for name in ("mesh2sdf", "sparc3d"):
        out = os.path.join(work, name + ".ply")
        r = {}
        try:
            if name == "mesh2sdf":
                cmd = [sys.executable, os.path.abspath(__file__), "--mesh2sdf-one", source, out,
                       "--size", str(args.size), "--mesh-scale", str(args.mesh_scale)]
                if args.with_resdf:
                    cmd.append("--with-resdf")
                info, wall = run_json(cmd, args.timeout)
                r["seconds"] = info["seconds"]
                if "resdf_seconds" in info:
                    r["resdf_seconds"] = info["resdf_seconds"]
                r["wall_seconds"] = wall
            else:
                cmd = [args.bin, "convert", source, "-o", out, "--resolution", str(args.size), "--json"]
                info, wall = run_json(cmd, args.timeout)
                r["seconds"] = info.get("total_seconds", wall)
                r["wall_seconds"] = wall
                r["watertight_reported"] = info.get("watertight")
            r["eval"] = evaluate(args, source, out)
        except subprocess.TimeoutExpired:
            r["error"] = "timeout after %.0f s" % args.timeout
        except Exception as e:
            r["error"] = str(e)[:300]
        rec[name] = r
    return rec


def f1_at(report, threshold=F1_THRESHOLD):
    for f in report.get("f1", []):
        if abs(f["threshold"] - threshold) < 1e-9:
            return f["f1"]
    return None


def fmt(x, spec):
    return "—" if x is None else format(x, spec)


def table(records):
    """Markdown: medians over meshes where both pipelines finished, then time-outs and errors."""
    both = [r for r in records if "eval" in r.get("mesh2sdf", {}) and "eval" in r.get("sparc3d", {})]
    lines = []
    lines.append("meshes: %d measured, %d with both outputs" % (len(records), len(both)))
    for name in ("mesh2sdf", "sparc3d"):
        timeouts = sum(1 for r in records if "timeout" in r.get(name, {}).get("error", ""))
        errors = sum(1 for r in records if r.get(name, {}).get("error") and "timeout" not in r[name]["error"])
        lines.append("%s: %d time-outs, %d errors" % (name, timeouts, errors))
    load_errors = sum(1 for r in records if "error" in r)
    if load_errors:
        lines.append("not loadable by trimesh: %d" % load_errors)
    lines.append("")
    lines.append("| median over %d meshes | mesh2sdf (fix=True) | sparc3d |" % len(both))
    lines.append("|---|---|---|")

    def col(name, f):
        return [f(r[name]) for r in both]

    rows = [
        ("cd×N (voxels)", lambda r: r["eval"]["cd_voxels"], ".3f"),
        ("point-to-surface cd×N", lambda r: r["eval"]["cd_surface"] * r["eval"]["options"]["resolution"], ".3f"),
        ("anc (0–100)", lambda r: r["eval"]["anc"], ".1f"),
        ("F1@0.005", lambda r: f1_at(r["eval"]), ".1f"),
        ("output faces", lambda r: r["eval"]["output_faces"], ".0f"),
        ("offset on closed sources (voxels)", lambda r: r["eval"].get("offset_voxels"), "+.3f"),
        ("time to the mesh (s)", lambda r: r["seconds"], ".2f"),
    ]
    for label, f, spec in rows:
        lines.append("| %s | %s | %s |" % (label, fmt(median(col("mesh2sdf", f)), spec), fmt(median(col("sparc3d", f)), spec)))
    for name_label, key in (("components kept (sum)", None), ("watertight outputs", "closed")):
        vals = []
        for name in ("mesh2sdf", "sparc3d"):
            if key is None:
                kept = sum(r[name]["eval"]["components_kept"] for r in both)
                total = sum(r[name]["eval"]["components_total"] for r in both)
                vals.append("%d / %d" % (kept, total))
            else:
                vals.append("%d / %d" % (sum(1 for r in both if r[name]["eval"]["output_closed"]), len(both)))
        lines.append("| %s | %s | %s |" % (name_label, vals[0], vals[1]))
    total = [sum(r[n]["seconds"] for r in both) for n in ("mesh2sdf", "sparc3d")]
    lines.append("| total time (s) | %.1f | %.1f |" % (total[0], total[1]))
    lines.append("")
    lines.append("| mesh | faces | cd×N m2s / s3d | F1@0.005 m2s / s3d | kept m2s / s3d | watertight m2s / s3d | time s m2s / s3d |")
    lines.append("|---|---|---|---|---|---|---|")
    for r in records:
        m, s = r.get("mesh2sdf", {}), r.get("sparc3d", {})

        def cell(x, f, spec):
            if "eval" not in x:
                return "timeout" if "timeout" in x.get("error", "") else "error"
            return fmt(f(x), spec)

        lines.append("| `%s` | %s | %s / %s | %s / %s | %s / %s | %s / %s | %s / %s |" % (
            r["mesh"][:60], r.get("source_faces", "—"),
            cell(m, lambda x: x["eval"]["cd_voxels"], ".3f"), cell(s, lambda x: x["eval"]["cd_voxels"], ".3f"),
            cell(m, lambda x: f1_at(x["eval"]), ".1f"), cell(s, lambda x: f1_at(x["eval"]), ".1f"),
            cell(m, lambda x: x["eval"]["components_kept"], "d"), cell(s, lambda x: x["eval"]["components_kept"], "d"),
            cell(m, lambda x: "yes" if x["eval"]["output_closed"] else "no", "s"),
            cell(s, lambda x: "yes" if x["eval"]["output_closed"] else "no", "s"),
            cell(m, lambda x: x["seconds"], ".1f"), cell(s, lambda x: x["seconds"], ".2f"),
        ))
    return "\n".join(lines) + "\n"


def read_jsonl(path):
    records = []
    if os.path.exists(path):
        with open(path) as f:
            for line in f:
                line = line.strip()
                if line:
                    records.append(json.loads(line))
    return records


def main():
    args = parse_args()
    if args.mesh2sdf_one:
        mesh2sdf_one(args.mesh2sdf_one[0], args.mesh2sdf_one[1], args.size, args.mesh_scale, args.with_resdf)
        return 0
    if args.summarize:
        sys.stdout.write(table(read_jsonl(args.summarize)))
        return 0
    if not args.corpus:
        print("give a CORPUS (folder or list) or --summarize JSONL", file=sys.stderr)
        return 2
    args.bin = binary(args.bin)
    jsonl = args.out + ".jsonl"
    done = {r["mesh"] for r in read_jsonl(jsonl)}
    meshes = list_meshes(args.corpus)
    if args.limit:
        meshes = meshes[: args.limit]
    with open(jsonl, "a") as out:
        for i, path in enumerate(meshes):
            if os.path.basename(path) in done:
                continue
            with tempfile.TemporaryDirectory(prefix="m2s_") as work:
                rec = measure(args, path, work)
            out.write(json.dumps(rec) + "\n")
            out.flush()
            m, s = rec.get("mesh2sdf", {}), rec.get("sparc3d", {})
            print("[%d/%d] %s  mesh2sdf %s  sparc3d %s" % (
                i + 1, len(meshes), rec["mesh"],
                m.get("error") or "%.1f s" % m.get("seconds", 0), s.get("error") or "%.2f s" % s.get("seconds", 0)),
                flush=True)
    text = table(read_jsonl(jsonl))
    with open(args.out + ".md", "w") as f:
        f.write(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
