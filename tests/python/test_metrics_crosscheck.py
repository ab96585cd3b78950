"""Checks `sparc3d eval` against an independent implementation (trimesh + scipy) of the
metrics of docs/QUALITY.md ("How we measure"): Chamfer distance, absolute normal consistency
and F1.

Both sides sample `N` points uniformly by area on each mesh, in the frame where the source's
bounding box is centred and its longest side is 1, pair every point with its nearest neighbour
on the other mesh, and average. They use different random samples, so they agree only within
sampling noise. Each number is a mean over N independent points (per direction), so its
standard error is about (per-point standard deviation) / sqrt(N) from the query points, and
as much again from the points they are paired with (the other mesh's sample), so sqrt(2)
times that; the difference of two implementations has sqrt(2) times more again, and we allow
5 standard errors of the difference: 5 * 2 * sd / sqrt(N).
The expected value of a nearest-neighbour distance also carries the sampling floor,
about ½·sqrt(A/N) for surface area A, but that bias is the same for both (same N, same
definition), so it cancels in the comparison. For F1, precision and recall are proportions
p over N points: standard error sqrt(p(1-p)/N), again times 2 and 5; a small absolute
slack (0.05 points) covers proportions near 0 or 1. The Rust side uses its fixed default
seed and this side fixed seeds, so the outcome is deterministic."""

import json
import pathlib

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
cKDTree = pytest.importorskip("scipy.spatial").cKDTree

from sparc3d_cli import ROOT, run
N = 100_000
RESOLUTION = 64
THRESHOLDS = [0.002, 0.005, 0.01]
Z = 5.0 * 2.0


def load(path, tmp):
    path = pathlib.Path(path)
    if path.suffix == ".obj":
        # Positions and faces only (trimesh would need Pillow for the texture coordinates).
        v, f = [], []
        for line in path.read_text().splitlines():
            parts = line.split()
            if parts and parts[0] == "v":
                v.append([float(x) for x in parts[1:4]])
            elif parts and parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(v) + i for i in idx]
                f.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
        return trimesh.Trimesh(vertices=np.array(v), faces=np.array(f), process=False)
    return trimesh.load(str(path), force="mesh", process=False)


def sample(mesh, center, inv, seed):
    """N area-uniform points in the evaluation frame, with the normals of their faces."""
    framed = trimesh.Trimesh(vertices=(mesh.vertices - center) * inv, faces=mesh.faces,
                             process=False)
    points, faces = trimesh.sample.sample_surface(framed, N, seed=seed)
    return points, framed.face_normals[faces]


def python_metrics(source, output):
    lo, hi = source.bounds
    center, inv = 0.5 * (lo + hi), 1.0 / float((hi - lo).max())
    ps, ns = sample(source, center, inv, seed=1)
    po, no = sample(output, center, inv, seed=2)
    d_so, j_so = cKDTree(po).query(ps)  # source → output
    d_os, j_os = cKDTree(ps).query(po)  # output → source
    c_so = np.abs((ns * no[j_so]).sum(1))
    c_os = np.abs((no * ns[j_os]).sum(1))
    m = {
        "cd": 0.5 * (d_so.mean() + d_os.mean()),
        "cd_se": 0.5 * np.sqrt(d_so.var() / N + d_os.var() / N),
        "anc": 50.0 * (c_so.mean() + c_os.mean()),
        "anc_se": 50.0 * np.sqrt(c_so.var() / N + c_os.var() / N),
        "f1": {},
    }
    for t in THRESHOLDS:
        precision = 100.0 * (d_os < t).mean()
        recall = 100.0 * (d_so < t).mean()
        f1 = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
        m["f1"][t] = (precision, recall, f1)
    return m


def proportion_tol(p):
    q = p / 100.0
    return Z * 100.0 * np.sqrt(q * (1.0 - q) / N) + 0.05


@pytest.mark.parametrize("name", ["sphere.obj", "cube.off", "wuson.stl"])
def test_eval_matches_trimesh_scipy(name, tmp_path):
    src = ROOT / "examples" / name
    out = tmp_path / "out.ply"
    run("convert", src, "-o", out, "--resolution", RESOLUTION)
    rust = json.loads(run("eval", src, out, "--resolution", RESOLUTION, "--samples", N, "--json").stdout)
    py = python_metrics(load(src, tmp_path), load(out, tmp_path))

    assert rust["options"]["samples"] == N
    assert abs(rust["cd"] - py["cd"]) <= Z * py["cd_se"] + 1e-7, (rust["cd"], py["cd"], py["cd_se"])
    assert rust["cd_voxels"] == pytest.approx(rust["cd"] * RESOLUTION)
    assert abs(rust["anc"] - py["anc"]) <= Z * py["anc_se"] + 1e-6, (rust["anc"], py["anc"])
    assert [f["threshold"] for f in rust["f1"]] == THRESHOLDS
    for f in rust["f1"]:
        precision, recall, f1 = py["f1"][f["threshold"]]
        assert abs(f["precision"] - precision) <= proportion_tol(precision), (f, precision)
        assert abs(f["recall"] - recall) <= proportion_tol(recall), (f, recall)
        # F1 is a smooth function of the two: its error is at most the larger of theirs.
        tol = max(proportion_tol(precision), proportion_tol(recall))
        assert abs(f["f1"] - f1) <= tol, (f, f1)
