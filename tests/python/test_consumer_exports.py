"""Each consumer's export read back the way that codebase's own loader reads it, and checked for
meaning, not only loading. No peer code is here: each `read_*` below mirrors the loader named in
docs/FORMAT.md ("Exports": file, function, lines) as read at that codebase's public head.

Meaning: the surface points lie on the item's watertight mesh placed in the consumer's frame
(the source mesh's bounding box centred, its longest side on the consumer's ±extent, computed
here from the source file, not from our code), and the signed distances agree with the winding
number of that mesh under the consumer's sign rule (positive inside for all four) on at least
99.9 % of the points farther than 1e-3 from the surface.

The job also holds a torus, a mesh without sharp edges: Dora and Hunyuan3D-2.1, whose own
samplers write nothing for it, leave it out (counted apart, exit 0); Step1X-3D writes it without
`sharp_surface`, which its autoencoder config (`with_sharp_data: False`) never reads; TripoSG
reads it as any other item."""

import glob
import json
import pathlib
import sys

import numpy as np
import pytest
import trimesh

from sparc3d_cli import ROOT, frozen_records, run, sparc3d_bin

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

MESHES = ["cube.off", "wuson.stl"]
TORUS = "torus.ply"  # generated: no edge sharper than 15 degrees once converted at 64
RESOLUTION = 64
# Half extent of each consumer's cube (docs/FORMAT.md: Hunyuan3D-2.1's normalize_mesh scale
# 0.9999; Dora's remesh and those that follow it, ±1).
EXTENT = {"hunyuan3d-2.1": 0.9999, "dora": 1.0, "step1x-3d": 1.0, "triposg": 1.0}


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("consumers")
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in MESHES:
        (meshes / name).write_bytes((ROOT / "examples" / name).read_bytes())
    trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=96,
                           minor_sections=48).export(meshes / TORUS)
    manifest = tmp / "m.jsonl"
    run("manifest", "build", meshes, "-o", manifest)
    config = tmp / "job.toml"
    config.write_text("[samples]\nseed = 3\n")
    path = tmp / "job"
    # --for: samples on, with the defaults that serve every vector-set consumer.
    run("init", path, "--manifest", manifest, "--resolution", RESOLUTION, "--config", config,
        "--for", "dora")
    run("run", path, "--workers", "1")
    return path


def ids_of(job, name):
    """The ids of the job's items whose source file is `name`."""
    records = frozen_records(job)
    return [r["id"] for r in records if r["uri"].endswith("/" + name)]


def export(job, fmt, out, *flags):
    """`sparc3d export` (exit 0 required); its stderr and its record."""
    r = run("export", job, "--format", fmt, "--out", out, *flags)
    return r.stderr, json.loads((out / ".sparc3d-export.json").read_text())


@pytest.fixture(scope="module")
def items(job, tmp_path_factory):
    """Per item id: its source mesh and its watertight output mesh (source frame)."""
    tmp = tmp_path_factory.mktemp("meshes")
    out = {}
    for rec in frozen_records(job):
        ply = tmp / (rec["id"] + ".ply")
        run("show", job, "--id", rec["id"], "-o", ply)
        out[rec["id"]] = (trimesh.load(rec["uri"], process=False, force="mesh"),
                          trimesh.load(ply, process=False, force="mesh"))
    return out


def consumer_frame(source, extent):
    """Source → consumer: bounding box centred, longest side onto ±extent."""
    lo, hi = source.bounds
    center, scale = (lo + hi) / 2, 2 * extent / (hi - lo).max()
    return lambda p: (np.asarray(p, np.float64) - center) * scale


def winding(mesh_v, mesh_f, points):
    """Generalised winding number of a closed mesh at points (Van Oosterom & Strackee)."""
    tri = mesh_v[mesh_f]
    out = np.empty(len(points))
    for lo in range(0, len(points), 32):
        a = tri[None, :, 0] - points[lo:lo + 32, None]
        b = tri[None, :, 1] - points[lo:lo + 32, None]
        c = tri[None, :, 2] - points[lo:lo + 32, None]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("pti,pti->pt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pti,pti->pt", a, b) * lc
               + np.einsum("pti,pti->pt", b, c) * la + np.einsum("pti,pti->pt", c, a) * lb)
        out[lo:lo + 32] = np.arctan2(det, den).sum(1) / (2 * np.pi)
    return out


def distance_to(mesh_v, mesh_f, points, k=24):
    """Distance from points to the mesh's triangles: exact point-triangle distances to the
    triangles of the k nearest points of a dense surface sample (trimesh.triangles.closest_point)."""
    from scipy.spatial import cKDTree
    m = trimesh.Trimesh(mesh_v, mesh_f, process=False)
    dense, face = trimesh.sample.sample_surface(m, 200_000, seed=1)
    _, near = cKDTree(dense).query(points, k=k)
    faces = face[near]                                           # [n, k] candidate triangles
    tris = m.triangles[faces.ravel()]
    pts = np.repeat(points, k, axis=0)
    closest = trimesh.triangles.closest_point(tris, pts)
    return np.linalg.norm(closest - pts, axis=1).reshape(len(points), k).min(1)


def check_meaning(name, fmt, items, surface, signed, rng):
    """`surface` [k, 3] and `signed` [m, 4] (xyz + distance, positive inside) of item `name`,
    in consumer `fmt`'s frame: on the mesh, and signed as its winding number says."""
    source, out = items[name]
    to_frame = consumer_frame(source, EXTENT[fmt])
    v, f = to_frame(out.vertices), np.asarray(out.faces)
    pick = rng.choice(len(surface), 2000, replace=False)
    d = distance_to(v, f, surface[pick].astype(np.float64))
    # f16 storage of the samples (2^-11 near 1) and the dense sample's spacing.
    assert np.quantile(d, 0.99) < 4e-3 and d.max() < 1e-2, (fmt, name, d.max())
    pick = rng.choice(len(signed), 1500, replace=False)
    pts, dist = signed[pick, :3].astype(np.float64), signed[pick, 3].astype(np.float64)
    far = np.abs(dist) > 1e-3
    inside = winding(v, f, pts[far]) > 0.5
    agree = (dist[far] > 0) == inside
    assert agree.mean() >= 0.999, (fmt, name, agree.mean())
    assert inside.any() and (~inside).any()


def read_hunyuan(item_dir, pc_size=30720, pc_sharp=30720, rng=None):
    """hy3dshape/data/dit_asl.py, AlignedShapeLatentDataset.decode (L247-259) and
    load_surface_sdf_points (L178-208): xyz, normal (renormalised), sharp flag."""
    uid = item_dir.name
    d = np.load(item_dir / "geo_data" / f"{uid}_surface.npz")
    rs, ss = d["random_surface"], d["sharp_surface"]
    parts = [np.c_[rs[rng.choice(len(rs), pc_size, replace=False)], np.zeros(pc_size)],
             np.c_[ss[rng.choice(len(ss), pc_sharp, replace=False)], np.ones(pc_sharp)]]
    x = np.concatenate(parts).astype(np.float32)
    x[:, 3:6] /= np.maximum(np.linalg.norm(x[:, 3:6], axis=1, keepdims=True), 1e-12)
    return x, d


def test_hunyuan3d_reads_every_item_in_its_frame_and_sign(job, items, tmp_path):
    out = tmp_path / "hy"
    said, record = export(job, "hunyuan3d-2.1", out)
    rng = np.random.default_rng(0)
    # The torus is left out, as Hunyuan3D-2.1's own sampler leaves it, and fails nothing.
    assert "1 left out: no sharp edges, as Hunyuan3D-2.1's own sampler" in said, said
    assert [x["id"] for x in record["left_out"]] == ids_of(job, TORUS) and not record["failed"]
    # The loader's glob(data_list + '/*') (dit_asl.py L149-155): every entry is an item.
    dirs = [pathlib.Path(p) for p in sorted(glob.glob(str(out) + "/*"))]
    assert len(dirs) == len(MESHES) and all(p.is_dir() for p in dirs), dirs
    by_stem = record["items"]
    for item_dir, rec in zip(dirs, by_stem):
        x, surf = read_hunyuan(item_dir, rng=rng)
        assert x.shape == (61440, 7)
        assert surf["random_surface"].dtype == np.float16
        assert surf["random_surface"].shape == surf["sharp_surface"].shape == (124928, 6)
        sdf = np.load(item_dir / "geo_data" / f"{item_dir.name}_sdf.npz")
        assert sdf["random_near_points"].shape == (249856, 3)
        assert sdf["sharp_near_points"].shape == (124928, 3)
        assert sdf["vol_label"].ndim == 1 and len(sdf["vol_label"]) == len(sdf["vol_points"])
        assert np.abs(sdf["vol_points"]).max() <= 1.05
        signed = np.concatenate([np.c_[sdf[k + "_points"], sdf[k + "_label"]]
                                 for k in ("vol", "random_near", "sharp_near")])
        check_meaning(rec["id"], "hunyuan3d-2.1", items, x[:, :3], signed, rng)


def read_dora(npz_path, n_sup=(21384, 10000, 10000), rng=None):
    """craftsman/data/objaverse.py, ObjaverseDataset._load_shape (L121-164) and
    _load_shape_supervision (L166-210)."""
    d = np.load(npz_path)
    coarse = np.nan_to_num(d["fps_coarse_surface"][:, 0, :], nan=1.0).astype(np.float32)
    sharp = np.nan_to_num(d["fps_sharp_surface"][:, 0, :], nan=1.0).astype(np.float32)
    sn, rp = d["sharp_near_surface"], d["rand_points"]
    a = sn[rng.choice(len(sn), n_sup[0], replace=False)]
    b = rp[:400000][rng.choice(400000, n_sup[1], replace=False)]
    c = rp[400000:][rng.choice(len(rp) - 400000, n_sup[2], replace=False)]
    return coarse, sharp, np.concatenate([a, b, c]), d


def test_dora_reads_every_listed_item_in_its_frame_and_sign(job, items, tmp_path):
    out = tmp_path / "dora"
    said, record = export(job, "dora", out)  # exit 0: an item left out is no failure
    rng = np.random.default_rng(1)
    assert "1 left out: no sharp edges, as Dora's own sampler" in said, said
    assert [x["id"] for x in record["left_out"]] == ids_of(job, TORUS) and not record["failed"]
    listed = json.load(open(out / "train.json"))  # paths opened as they are (L123)
    records = record["items"]
    assert len(listed) == len(MESHES)
    # Its data module also opens val.json, its launch script test.json (both drawn from the
    # items, at most 16).
    checks = json.load(open(out / "val.json"))
    assert checks == json.load(open(out / "test.json")) and 0 < len(checks) <= 16
    assert set(checks) <= set(listed)
    for path, rec in zip(listed, records):
        coarse, sharp, sup, d = read_dora(path, rng=rng)
        rp = d["rand_points"]  # 400000 near rows, then up to 200000 volume rows
        assert rp.dtype == np.float32 and rp.shape[1] == 4 and 410000 <= len(rp) <= 600000
        assert coarse.shape == sharp.shape == (32768, 6)
        # The near block first (σ 0.001 and 0.005), then the volume in ±1.05.
        rp = d["rand_points"]
        assert np.abs(rp[:400000, 3]).max() < 0.1 and np.abs(rp[400000:, :3]).max() <= 1.05
        # Farthest points spread: no two of the coarse set closer than a tenth of the mean
        # spacing of a random subset of the same size would be unusual; check they are distinct.
        assert len(np.unique(coarse[:, :3], axis=0)) == len(coarse)
        check_meaning(rec["id"], "dora", items, coarse[:, :3], sup, rng)


def read_step1x3d(root, uid, with_sharp_data, rng, n_samples=32768, n_supervision=10000):
    """step1x3d_geometry/data/base.py, BaseDataset._load_shape_from_occupancy_or_sdf (L104-159,
    sampling_strategy "random") and _load_shape_supervision_occupancy_or_sdf (L161-202,
    supervision_type "occupancy"): `sharp_surface` read only with `with_sharp_data`."""
    data = np.load(f"{root}/surfaces/{uid}.npz")
    surface = data["surface"]
    if with_sharp_data:
        sharp_surface = data["sharp_surface"]
    ind = rng.choice(surface.shape[0], n_samples, replace=True)
    ret = {"surface": surface[ind].astype(np.float32)}
    if with_sharp_data:
        ret["sharp_surface"] = sharp_surface[ind].astype(np.float32)
    v = np.concatenate([data["volume_rand_points"], data["near_surface_points"]], axis=0)
    j = rng.choice(v.shape[0], n_supervision, replace=False)
    ret["rand_points"] = v[j, :3].astype(np.float32)
    ret["occupancies"] = np.where(v[j, 3:].flatten() < 1e-3, 0, 1).astype(np.float32)
    return ret, v


def test_step1x3d_reads_every_listed_uid_in_its_frame_and_sign(job, items, tmp_path):
    out = tmp_path / "s1x"
    said, record = export(job, "step1x-3d", out)
    rng = np.random.default_rng(2)
    uids = json.load(open(out / "train.json"))
    records = record["items"]
    # Every item, the torus too: its autoencoder config reads no sharp data.
    assert len(uids) == len(MESHES) + 1 and not record["left_out"] and not record["failed"]
    torus = ids_of(job, TORUS)
    assert "1 of them without sharp_surface (no sharp edges)" in said, said
    assert [x["id"] for x in record["noted"]] == torus
    checks = json.load(open(out / "val.json"))  # Objaverse.py L40-43 builds a val split
    assert checks == json.load(open(out / "test.json")) and set(checks) <= set(uids)
    for uid, rec in zip(uids, records):
        # michelangelo.yaml: with_sharp_data False.
        got, v = read_step1x3d(out, uid, False, rng)
        assert got["surface"].shape == (32768, 6) and got["occupancies"].any()
        check_meaning(rec["id"], "step1x-3d", items, got["surface"][:, :3], v, rng)
        # The diffusion configs' with_sharp_data True: every item with sharp edges reads; the
        # torus stops at the key it lacks, never at made-up rows.
        if rec["id"] in torus:
            with pytest.raises(KeyError, match="sharp_surface"):
                read_step1x3d(out, uid, True, rng)
        else:
            sharp = read_step1x3d(out, uid, True, rng)[0]["sharp_surface"]
            assert sharp.shape == (32768, 6)


def test_triposg_reads_every_item_in_its_frame(job, items, tmp_path):
    out = reader.run_export(job, "triposg", tmp_path / "tsg", binary=sparc3d_bin())
    rng = np.random.default_rng(3)
    records = json.loads((out / ".sparc3d-export.json").read_text())["items"]
    assert len(records) == len(MESHES) + 1  # it reads surface points alone: the torus too
    for rec in records:
        # scripts/inference_vae.py, load_surface (L12-23).
        d = np.load(out / rec["files"][0], allow_pickle=True).tolist()
        p, n = d["surface_points"], d["surface_normals"]
        assert p.shape == n.shape and p.shape[1] == 3 and len(p) >= 204800
        i = rng.choice(len(p), 204800, replace=False)
        x = np.concatenate([p[i], n[i]], -1).astype(np.float32)[None]
        assert x.shape == (1, 204800, 6)
        source, out_mesh = items[rec["id"]]
        v = consumer_frame(source, 1.0)(out_mesh.vertices)
        d = distance_to(v, np.asarray(out_mesh.faces), x[0, :2000, :3].astype(np.float64))
        assert np.quantile(d, 0.99) < 4e-3, d.max()
        assert np.abs(np.linalg.norm(x[0, :, 3:], axis=1) - 1).max() < 2e-3


def test_a_job_without_what_a_consumer_needs_is_refused_before_anything_is_written(job, tmp_path):
    small = tmp_path / "small.toml"
    small.write_text("[samples]\nenabled = true\nsurface = 1000\nnear = 300\n")
    manifest = tmp_path / "m.jsonl"
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "cube.off").write_bytes((ROOT / "examples" / "cube.off").read_bytes())
    run("manifest", "build", meshes, "-o", manifest)
    path = tmp_path / "job"
    run("init", path, "--manifest", manifest, "--resolution", 32, "--config", small)
    for fmt, key in [("dora", "samples.near"), ("triposg", "samples.surface"),
                     ("hunyuan3d-2.1", "samples.surface")]:
        r = run("export", path, "--format", fmt, "--out", tmp_path / fmt, check=False)
        assert r.returncode == 2 and key in r.stderr, (fmt, r.stderr)
        assert f"--for {fmt}" in r.stderr, r.stderr  # the preset that makes such a job
        assert not (tmp_path / fmt).exists()


def written_surface(fmt, out, rec):
    """The surface points `fmt` wrote for item `rec` of the export record, [k, 3]."""
    path = out / rec["files"][0]
    if fmt == "triposg":
        return np.load(path, allow_pickle=True).tolist()["surface_points"]
    d = np.load(path)
    key = {"hunyuan3d-2.1": "random_surface", "step1x-3d": "surface"}.get(fmt)
    return d["fps_coarse_surface"][:, 0, :3] if fmt == "dora" else d[key][:, :3]


@pytest.mark.parametrize("fmt", ["hunyuan3d-2.1", "dora", "step1x-3d", "triposg"])
def test_every_frame_a_format_offers_is_the_frame_it_writes(job, items, tmp_path, fmt):
    """`--frame` means one thing for every format (docs/FORMAT.md, "Frames"): `normalized`
    writes the points on the watertight mesh in the job's normalized frame (2·(x − center)·scale,
    center and scale as the item's npz files carry them), `source` on it in the source frame."""
    vecset = reader.run_export(job, "vecset-npz", tmp_path / "v", binary=sparc3d_bin())
    norm = {it["id"]: (np.asarray(it["center"]), float(it["scale"]))
            for it in reader.iter_export(vecset)}
    rng = np.random.default_rng(4)
    for frame in ("normalized", "source"):
        out = tmp_path / frame
        said, record = export(job, fmt, out, "--frame", frame)
        assert record["frame"] == frame and f"frame {frame})" in said, said
        assert record["items"]
        for rec in record["items"]:
            _, mesh = items[rec["id"]]
            center, scale = norm[rec["id"]]
            v = np.asarray(mesh.vertices, np.float64)
            if frame == "normalized":
                v = 2 * (v - center) * scale
            points = written_surface(fmt, out, rec).astype(np.float64)
            pick = rng.choice(len(points), 2000, replace=False)
            d = distance_to(v, np.asarray(mesh.faces), points[pick])
            extent = (v.max(0) - v.min(0)).max()
            assert np.quantile(d, 0.99) < 2e-3 * extent, (fmt, frame, d.max() / extent)


def test_a_frame_a_format_does_not_have_is_refused(job, tmp_path):
    for fmt, frame in [("vecset-npz", "consumer"), ("cubvh", "normalized"),
                       ("trellis2", "source"), ("direct3d-s2", "source")]:
        out = tmp_path / fmt
        r = run("export", job, "--format", fmt, "--frame", frame, "--out", out, check=False)
        assert r.returncode == 2 and f"not {frame}" in r.stderr, (fmt, r.stderr)
        assert not out.exists()
