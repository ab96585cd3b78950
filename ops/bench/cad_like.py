#!/usr/bin/env python3
"""Which meshes of a corpus are CAD-like (docs/QUALITY.md, "Refinement against renderings").

Per mesh (trimesh, vertices merged): `curved_share`, the share of the interior edge length whose
dihedral angle is between 1 and 30 degrees (curved surfaces tessellated), and `sharp_len_rel`,
the length of edges at 30 degrees or more over the square root of the area. A mesh is CAD-like
when curved_share < 0.1 and sharp_len_rel >= 1: flat faces meeting at sharp edges.

    python3 ops/bench/cad_like.py CORPUS cad.json

Needs numpy and trimesh.
"""
import argparse
import json
import os

import numpy as np
import trimesh


def measure(path):
    """The two figures of one mesh (and its face count), or its error."""
    try:
        m = trimesh.load(path, force="mesh", process=True)
        m.merge_vertices()
        ang = m.face_adjacency_angles
        edges = m.face_adjacency_edges
        el = np.linalg.norm(m.vertices[edges[:, 0]] - m.vertices[edges[:, 1]], axis=1)
        sharp = el[ang >= np.radians(30)].sum()
        smooth_share = el[(ang > np.radians(1)) & (ang < np.radians(30))].sum() / max(el.sum(), 1e-30)
        return {"sharp_len_rel": float(sharp / np.sqrt(m.area)),
                "curved_share": float(smooth_share), "faces": len(m.faces)}
    except Exception as e:  # a mesh trimesh cannot read is recorded, not fatal
        return {"error": str(e)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("corpus", help="folder of meshes")
    ap.add_argument("out", help="JSON file written: mesh name -> figures")
    args = ap.parse_args()
    out = {f: measure(os.path.join(args.corpus, f)) for f in sorted(os.listdir(args.corpus))}
    with open(args.out, "w") as f:
        json.dump(out, f, indent=0)


if __name__ == "__main__":
    main()
