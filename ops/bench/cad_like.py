#!/usr/bin/env python3
"""Which meshes of a corpus are CAD-like (docs/QUALITY.md, "Refinement against renderings").

Per mesh (trimesh, vertices merged): `curved_share`, the share of the interior edge length whose
dihedral angle is between 1 and 30 degrees (curved surfaces tessellated), and `sharp_len_rel`,
the length of edges at 30 degrees or more over the square root of the area. A mesh is CAD-like
when curved_share < 0.1 and sharp_len_rel >= 1: flat faces meeting at sharp edges.

    python3 ops/bench/cad_like.py CORPUS cad.json

Needs numpy and trimesh.
"""
import sys, os, json, numpy as np, trimesh

out = {}
for f in sorted(os.listdir(sys.argv[1])):
    p = os.path.join(sys.argv[1], f)
    try:
        m = trimesh.load(p, force='mesh', process=True)
        m.merge_vertices()
        ang = m.face_adjacency_angles
        el = np.linalg.norm(m.vertices[m.face_adjacency_edges[:, 0]] - m.vertices[m.face_adjacency_edges[:, 1]], axis=1)
        sharp = el[ang >= np.radians(30)].sum()
        smooth_share = el[(ang > np.radians(1)) & (ang < np.radians(30))].sum() / max(el.sum(), 1e-30)
        out[f] = {"sharp_len_rel": float(sharp / np.sqrt(m.area)), "curved_share": float(smooth_share), "faces": len(m.faces)}
    except Exception as e:
        out[f] = {"error": str(e)}
json.dump(out, open(sys.argv[2], 'w'), indent=0)
