#!/usr/bin/env python3
"""Quality of sparc3d's vector-set samples against the source meshes (docs/QUALITY.md).

For every item of an export folder written by `sparc3d export JOB --format vecset-npz` (source
frame) whose source is closed (trimesh: watertight and consistently wound), on a seeded subset
of its volume and near samples:

- **sign errors**: the stored side (`sdf < 0`) against the generalised winding number of the
  source (solid angles, brute force in numpy), in %;
- **distance error**: |stored |sdf| − distance to the source surface|, median and 99th
  percentile, in voxels of the job's grid (brute force over the source's triangles);
- **components represented**, for every source (closed or not): source components at least
  2 voxels wide whose area-sampled points lie ≥ 90 % within 2 voxels of a stored surface
  sample.

    python3 ops/bench/samples_quality.py JOB EXPORT_DIR [--points 1000] [--max-faces 40000]

Needs numpy, scipy and trimesh; not run in CI (brute force, minutes per mesh).
"""

import argparse
import json
import pathlib
import sys

import numpy as np
import trimesh
from scipy.spatial import cKDTree


def winding_number(v, f, q, chunk=2048):
    """Generalised winding number of points q [m, 3] for the mesh (v, f)."""
    tri = v[f]
    out = np.zeros(len(q))
    for s in range(0, len(tri), chunk):
        t = tri[s:s + chunk][None] - q[:, None, None, :]  # [m, k, 3, 3]
        a, b, c = t[:, :, 0], t[:, :, 1], t[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("mki,mki->mk", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("mki,mki->mk", a, b) * lc
               + np.einsum("mki,mki->mk", b, c) * la + np.einsum("mki,mki->mk", c, a) * lb)
        out += 2 * np.arctan2(det, den).sum(1)
    return out / (4 * np.pi)


def distance(v, f, q, chunk=4096):
    """Unsigned distance from points q to the triangles (v, f), brute force."""
    best = np.full(len(q), np.inf)
    tri = v[f]
    for s in range(0, len(tri), chunk):
        t = tri[s:s + chunk]
        for i in range(len(q)):
            p = trimesh.triangles.closest_point(t, np.repeat(q[i:i + 1], len(t), 0))
            best[i] = min(best[i], np.sqrt(((p - q[i]) ** 2).sum(1)).min())
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("job")
    ap.add_argument("export")
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--max-faces", type=int, default=40000)
    args = ap.parse_args()
    manifest = [json.loads(l) for l in (pathlib.Path(args.job) / "manifest.jsonl").read_text().splitlines()]
    uri = {}
    for m in manifest:
        rec = m.get("record", m)
        uri[rec["id"]] = rec["uri"]
    rng = np.random.default_rng(0)
    rows = []
    for path in sorted(pathlib.Path(args.export).glob("*.npz")):
        z = np.load(path)
        assert str(z["frame"]) == "source"
        voxel = 1.0 / (float(z["scale"]) * int(z["resolution"]))
        src = trimesh.load(uri[path.stem], force="mesh", process=False)
        if len(src.faces) == 0:
            continue
        v, f = np.asarray(src.vertices, float), np.asarray(src.faces)
        row = {"id": path.stem[:12], "faces": len(f)}
        # Components represented.
        tree = cKDTree(z["surface_points"].astype(float))
        kept = total = 0
        # `repair=False`: trimesh's split otherwise fills the holes of open components, and
        # points sampled on those patches lie nowhere near any surface.
        for part in src.split(only_watertight=False, repair=False):
            if part.extents.max() < 2 * voxel or part.area <= 0:
                continue
            total += 1
            pts = part.sample(200, seed=0) if hasattr(part, "sample") else part.vertices
            d, _ = tree.query(pts)
            kept += int(np.mean(d <= 2 * voxel) >= 0.9)
        row["components"] = f"{kept}/{total}"
        closed = src.is_watertight and src.is_winding_consistent
        if closed and len(f) <= args.max_faces:
            for kind in ("volume", "near"):
                pts = z[f"{kind}_points"].astype(float)
                sdf = z[f"{kind}_sdf"].astype(float)
                pick = rng.choice(len(pts), min(args.points, len(pts)), replace=False)
                wn = winding_number(v, f, pts[pick])
                if src.volume < 0:
                    wn = -wn
                row[f"{kind}_sign_err_%"] = round(100 * np.mean((wn > 0.5) != (sdf[pick] < 0)), 3)
                err = np.abs(distance(v, f, pts[pick]) - np.abs(sdf[pick])) / voxel
                row[f"{kind}_dist_err_vox_med"] = round(float(np.median(err)), 4)
                row[f"{kind}_dist_err_vox_p99"] = round(float(np.quantile(err, 0.99)), 4)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
