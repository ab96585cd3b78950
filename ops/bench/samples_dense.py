#!/usr/bin/env python3
"""Vector-set samples of the common dense-grid pipeline, written as `vecset-npz` files so that
`ops/bench/samples_quality.py` measures them exactly as it measures sparc3d's (docs/QUALITY.md).

For every file of EXPORT_DIR (written by `sparc3d export JOB --format vecset-npz`), the item's
source mesh goes through the pipeline of `compare_mesh2sdf.py` (mesh2sdf's distance grid of
SIZE³ over the mesh scaled into [-MESH_SCALE, MESH_SCALE], marching cubes of |d| at one voxel,
the largest component: `mesh2sdf.compute(..., fix=True)`), and from that watertight mesh:

- surface points: area-uniform (trimesh `sample`, seed 0), as many as sparc3d's;
- near and volume points: the first `--points` of sparc3d's own near and volume points (the same
  positions, so only the values differ), with their exact distance to the pipeline's mesh
  (trimesh `closest_point`) and their side of it (see `side`); this is the best the
  pipeline's mesh allows, whatever interpolation a training script then uses.

`scale` and `resolution` are copied from sparc3d's file, so both are measured in voxels of the
sparc3d job's grid.

    python3 -m venv /tmp/m2s && /tmp/m2s/bin/pip install mesh2sdf scikit-image trimesh scipy rtree
    /tmp/m2s/bin/python ops/bench/samples_dense.py JOB EXPORT_DIR OUT_DIR [--size 256]
    /tmp/m2s/bin/python ops/bench/samples_quality.py JOB OUT_DIR --points 400

Slow (mesh2sdf is single-threaded); not run in CI.
"""

import argparse
import json
import pathlib
import sys
import tempfile

import numpy as np
import trimesh

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from compare_mesh2sdf import mesh2sdf_one  # noqa: E402  (the pipeline, one implementation)


def side(mesh, pts, closest, dist, face):
    """Whether each point is inside the closed mesh: from the closest triangle's outward normal
    where the direction to the point is clearly along it (|cos| > 0.5), else from trimesh's ray
    test (`contains`, exact but slow: about 20 s per 400 points on 300k triangles)."""
    normals = mesh.face_normals[face] * (1.0 if mesh.volume >= 0 else -1.0)
    along = np.einsum("ij,ij->i", pts - closest, normals) / np.maximum(dist, 1e-300)
    inside = along < 0
    unsure = np.abs(along) <= 0.5
    if unsure.any():
        inside[unsure] = mesh.contains(pts[unsure])
    return inside


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("job")
    ap.add_argument("export")
    ap.add_argument("out")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--mesh-scale", type=float, default=0.8)
    ap.add_argument("--points", type=int, default=400)
    args = ap.parse_args()
    manifest = (pathlib.Path(args.job) / "manifest.jsonl").read_text().splitlines()
    uri = {}
    for line in manifest:
        rec = json.loads(line)
        rec = rec.get("record", rec)
        uri[rec["id"]] = rec["uri"]
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for path in sorted(pathlib.Path(args.export).glob("*.npz")):
        if (out / path.name).exists():
            continue
        z = np.load(path)
        with tempfile.TemporaryDirectory() as tmp:
            fixed_path = str(pathlib.Path(tmp) / "fixed.ply")
            mesh2sdf_one(uri[path.stem], fixed_path, args.size, args.mesh_scale, False)
            fixed = trimesh.load(fixed_path, force="mesh", process=False)
        surface, _ = trimesh.sample.sample_surface(fixed, len(z["surface_points"]), seed=0)
        arrays = {
            "frame": np.array("source"),
            "scale": z["scale"],
            "resolution": z["resolution"],
            "surface_points": surface.astype(np.float32),
        }
        for kind in ("near", "volume"):
            pts = z[f"{kind}_points"][: args.points].astype(np.float64)
            closest, dist, face = trimesh.proximity.closest_point(fixed, pts)
            inside = side(fixed, pts, closest, dist, face)
            arrays[f"{kind}_points"] = pts.astype(np.float32)
            arrays[f"{kind}_sdf"] = np.where(inside, -dist, dist).astype(np.float32)
        np.savez(out / path.name, **arrays)
        print(path.stem[:12], len(fixed.faces), "faces", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
