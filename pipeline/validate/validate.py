#!/usr/bin/env python3
"""Checks extracted meshes against their sources with pymeshlab (used by `sparc3d validate`).

Protocol: one JSON object per line on stdin, one answer per line on stdout, in order:

    in:  {"id": "...", "output": "out.ply", "source": "src.ply", "voxel": 0.0039,
          "max_hausdorff_voxels": 3.0, "hausdorff_samples": 50000}
    out: {"id": "...", "ok": true, "checks": {...}, "measures": {...}, "error": null}

`voxel` is the length of one voxel in the meshes' frame. The checks (docs/VALIDATION.md):

- watertight:  0 boundary edges
- manifold:    0 non-two-manifold edges and 0 non-two-manifold vertices
- oriented:    0 edges whose two faces traverse it in the same direction
- volume:      the enclosed volume exists (closed mesh) and is positive (outward normals)
- components:  at least 1 (a surface came out); more than the source is expected where
               sheets inside closed parts become thin cavities, and a dropped part shows in
               the source-to-output Hausdorff distance
- hausdorff:   Hausdorff distance (both ways, pymeshlab's filter) within the limit in voxels

`python3 validate.py --probe` prints the versions and exits 0 when pymeshlab imports.
"""

import json
import sys


def inconsistent_edges(faces):
    """Edges traversed in the same direction by two faces (0 on a consistently oriented
    mesh), counted once per undirected edge."""
    import numpy as np

    if len(faces) == 0:
        return 0
    f = np.asarray(faces, dtype=np.int64)
    half = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    directed, counts = np.unique(half, axis=0, return_counts=True)
    dup = directed[counts > 1]
    if len(dup) == 0:
        return 0
    return int(len(np.unique(np.sort(dup, axis=1), axis=0)))


def hausdorff(ms, sampled, target, samples, maxdist):
    import pymeshlab

    r = ms.get_hausdorff_distance(
        sampledmesh=sampled,
        targetmesh=target,
        samplevert=True,
        sampleface=True,
        samplenum=int(samples),
        maxdist=pymeshlab.PureValue(maxdist),
    )
    return {"max": float(r["max"]), "mean": float(r["mean"]), "n": int(r["n_samples"])}


def check_one(req):
    """Measures one output mesh against its source; returns the answer object."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(req["output"])
    out_id = ms.current_mesh_id()
    out = ms.current_mesh()
    faces = out.face_matrix()
    topo = ms.get_topological_measures()
    geo = ms.get_geometric_measures()
    volume = geo.get("mesh_volume")
    measures = {
        "faces": int(out.face_number()),
        "vertices": int(out.vertex_number()),
        "boundary_edges": int(topo["boundary_edges"]),
        "non_two_manifold_edges": int(topo["non_two_manifold_edges"]),
        "non_two_manifold_vertices": int(topo["non_two_manifold_vertices"]),
        "is_mesh_two_manifold": bool(topo["is_mesh_two_manifold"]),
        "components": int(topo["connected_components_number"]),
        "inconsistent_edges": inconsistent_edges(faces),
        "volume": None if volume is None else float(volume),
    }
    source_components = None
    if req.get("source"):
        ms.load_new_mesh(req["source"])
        src_id = ms.current_mesh_id()
        # The source as loaded may repeat positions (seams of OBJ files, STL triangles).
        ms.meshing_remove_duplicate_vertices()
        source_components = int(ms.get_topological_measures()["connected_components_number"])
        diag = max(ms.mesh(out_id).bounding_box().diagonal(),
                   ms.mesh(src_id).bounding_box().diagonal())
        samples = req.get("hausdorff_samples", 50000)
        # The default limit (50% of the diagonal) would ignore far points: allow all.
        to_src = hausdorff(ms, out_id, src_id, samples, 2.0 * diag)
        to_out = hausdorff(ms, src_id, out_id, samples, 2.0 * diag)
        voxel = float(req.get("voxel") or 0.0)
        measures.update({
            "source_components": source_components,
            "hausdorff_output_to_source": to_src["max"],
            "hausdorff_source_to_output": to_out["max"],
            "hausdorff": max(to_src["max"], to_out["max"]),
            "mean_output_to_source": to_src["mean"],
            "mean_source_to_output": to_out["mean"],
            "voxel": voxel,
            "hausdorff_voxels": (max(to_src["max"], to_out["max"]) / voxel) if voxel > 0 else None,
        })
    checks = {
        "watertight": measures["boundary_edges"] == 0,
        "manifold": measures["non_two_manifold_edges"] == 0
        and measures["non_two_manifold_vertices"] == 0,
        "oriented": measures["inconsistent_edges"] == 0,
        "volume": volume is not None and volume > 0,
    }
    if source_components is not None:
        checks["components"] = measures["components"] >= 1
        limit = req.get("max_hausdorff_voxels")
        hv = measures["hausdorff_voxels"]
        checks["hausdorff"] = limit is None or (hv is not None and hv <= float(limit))
    return {"id": req.get("id"), "ok": all(checks.values()), "checks": checks,
            "measures": measures, "error": None}


def main():
    if "--probe" in sys.argv[1:]:
        import numpy
        import pymeshlab  # noqa: F401

        try:
            from importlib.metadata import version as dist_version

            version = dist_version("pymeshlab")
        except Exception:
            version = "unknown"
        print(json.dumps({"python": sys.version.split()[0], "pymeshlab": version,
                          "numpy": numpy.__version__}))
        return 0
    while True:
        line = sys.stdin.readline()
        if not line:
            return 0
        if not line.strip():
            continue
        req = {}
        try:
            req = json.loads(line)
            answer = check_one(req)
        except Exception as e:  # one bad item must not end the batch
            answer = {"id": req.get("id"), "ok": False, "checks": {}, "measures": {},
                      "error": f"{type(e).__name__}: {e}"}
        sys.stdout.write(json.dumps(answer) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    sys.exit(main())
