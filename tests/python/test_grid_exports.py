"""The grid consumers' exports read back the way each consumer reads them.

TRELLIS.2 (`--format trellis2`): `trellis2/datasets/flexi_dual_grid.py` `FlexiDualGridDataset`
(`filter_metadata`, `read_mesh`, `read_dual_grid`) over the folders of `data_dir.json`
(`trellis2/datasets/components.py` `StandardDatasetBase.__init__`), and
`o-voxel/o_voxel/io/vxz.py` `read_vxz` for the `.vxz` container, here decoded by a reader written
from the format's description (docs/FORMAT.md, "Exports").

Direct3D-S2 (`--format direct3d-s2`): `direct3d_s2/models/autoencoders/ss_vae.py`
`SparseSDFVAE.encode` (the batch) and `sparse2mesh` (the dense res³ grid filled with +1, index i at
2i/res − 1); signs checked against the winding number of the item's watertight mesh."""

import json
import pickle
import sys

import numpy as np
import pytest

from sparc3d_cli import ROOT, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

pytest.importorskip("zstandard")
from vxz_reader import read_vxz  # noqa: E402 (needs zstandard)

MESHES = ["cube.off", "wuson.stl"]
T2_RES = 48
D3_RES = 128  # object_span 0.95 leaves 3.2 free cells per side (3 needed)


# A unit cube without its top face: an open surface, which becomes a shell reaching beyond
# its box.
OPEN_BOX = """OFF
8 5 0
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
4 0 3 2 1
4 0 1 5 4
4 1 2 6 5
4 2 3 7 6
4 3 0 4 7
"""


def make_job(tmp, resolution=None, config="", extra=(), preset=None):
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in MESHES:
        (meshes / name).write_bytes((ROOT / "examples" / name).read_bytes())
    for name, text in extra:
        (meshes / name).write_text(text)
    manifest = tmp / "m.jsonl"
    run("manifest", "build", meshes, "-o", manifest)
    toml = tmp / "job.toml"
    toml.write_text(config)
    path = tmp / "job"
    flags = (["--resolution", resolution] if resolution else []) + (
        ["--for", preset] if preset else [])
    run("init", path, "--manifest", manifest, "--config", toml, *flags)
    run("run", path, "--workers", "1")
    records = [json.loads(line) for line in manifest.read_text().splitlines()]
    return path, records


def load_item(root, sha):
    """`FlexiDualGridDataset.get_instance`: `read_mesh` (objects concatenated, the longest side
    scaled to 0.99999 around the box centre) and `read_dual_grid`."""
    dump = pickle.loads((pathlib_join(root["mesh_dump"], sha + ".pickle")).read_bytes())
    vs, fs, start = [], [], 0
    for o in dump["objects"]:
        if o["vertices"].size == 0 or o["faces"].size == 0:
            continue
        vs.append(o["vertices"])
        fs.append(o["faces"] + start)
        start += len(o["vertices"])
    v, f = np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int64)
    coords, attrs, header = read_vxz(pathlib_join(root["dual_grid"], sha + ".vxz"))
    return v, f, coords, attrs, header


def pathlib_join(folder, name):
    import pathlib
    return pathlib.Path(folder) / name


def filter_metadata(root_dirs, max_active_voxels=1_000_000, max_num_faces=None):
    """`StandardDatasetBase.__init__` (one metadata.csv per listed folder, combined on sha256)
    and `FlexiDualGridDataset.filter_metadata` with `min_aesthetic_score=None`: with pandas as
    upstream when it is installed, else the same steps with the csv module (pandas reads the
    literal `True` as a boolean)."""
    try:
        import pandas as pd
    except ImportError:
        return _filter_metadata_csv(root_dirs, max_active_voxels, max_num_faces)
    metadata = None
    for folder in root_dirs.values():
        m = pd.read_csv(pathlib_join(folder, "metadata.csv")).set_index("sha256")
        metadata = m if metadata is None else metadata.combine_first(m)
    metadata = metadata[metadata["dual_grid_converted"] == True]  # noqa: E712 (as upstream)
    metadata = metadata[metadata["dual_grid_size"] <= max_active_voxels]
    if max_num_faces is not None:
        metadata = metadata[metadata["num_faces"] <= max_num_faces]
    return {sha: dict(row) for sha, row in metadata.iterrows()}


def _filter_metadata_csv(root_dirs, max_active_voxels, max_num_faces):
    import csv

    rows = {}
    for folder in root_dirs.values():
        with open(pathlib_join(folder, "metadata.csv"), newline="") as f:
            for row in csv.DictReader(f):
                rows.setdefault(row["sha256"], {}).update(row)
    return {sha: r for sha, r in rows.items()
            if r.get("dual_grid_converted") == "True"
            and int(r["dual_grid_size"]) <= max_active_voxels
            and (max_num_faces is None or int(r["num_faces"]) <= max_num_faces)}


@pytest.fixture(scope="module")
def trellis2(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("trellis2")
    job, records = make_job(tmp, T2_RES)
    out = tmp / "out"
    # Not made for TRELLIS.2: refused in its frame, naming the preset; written on the job's
    # own grid with --frame normalized, the rescaling named.
    r = run("export", job, "--format", "trellis2", "--out", out, check=False)
    assert r.returncode == 2 and "--for trellis2@%d" % T2_RES in r.stderr, r.stderr
    assert not out.exists()
    r = run("export", job, "--format", "trellis2", "--frame", "normalized", "--out", out)
    assert "warning" in r.stderr and "0.99999" in r.stderr, r.stderr  # the frame is named
    # No [attributes]: no PBR voxels, said once in the summary, not an error.
    assert r.stderr.count("without pbr_voxels") == 1, r.stderr
    assert not list(out.glob("pbr_voxels_*"))
    return out, records


def test_trellis2_data_dir_lists_folders_each_with_its_metadata(trellis2):
    out, records = trellis2
    data_dir = json.loads((out / "data_dir.json").read_text())
    (root,) = data_dir.values()
    assert set(root) == {"base", "mesh_dump", "dual_grid", "asset_stats"}
    assert root["dual_grid"].endswith("dual_grid_%d" % T2_RES)
    shas = sorted(r["sha256"] for r in records)
    for folder in root.values():
        assert (pathlib_join(folder, "metadata.csv")).is_file(), folder
    kept = filter_metadata(root)
    assert sorted(kept) == shas
    assert all(int(r["num_faces"]) > 0 for r in kept.values())


def test_trellis2_dual_vertices_lie_in_their_voxels_and_overlay_the_mesh(trellis2):
    out, records = trellis2
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    for rec in records:
        v, f, coords, attrs, header = load_item(root, rec["sha256"])
        assert header["attr"] == [["vertices", 3], ["intersected", 1]]
        assert coords.min() >= 0 and coords.max() < T2_RES
        assert len(np.unique(coords, axis=0)) == len(coords)
        local = attrs["vertices"] / 255.0  # in [0, 1]: inside its voxel by construction
        assert attrs["intersected"].max() < 8 and attrs["intersected"].any()
        # World positions in TRELLIS.2's aabb [-0.5, 0.5]^3 (flexible_dual_grid_to_mesh).
        dual = (coords + local) / T2_RES - 0.5
        # The dump's vertices are in the same frame: every dual vertex is within a voxel of
        # the mesh (nearest vertex, the extracted mesh having one per crossed edge) and every
        # mesh vertex lies in or next to an active voxel.
        from scipy.spatial import cKDTree
        d, _ = cKDTree(v).query(dual)
        assert d.max() < np.sqrt(3) / T2_RES, (rec["uri"], d.max() * T2_RES)
        voxel = np.floor((v + 0.5) * T2_RES).astype(np.int64)
        active = {tuple(c) for c in coords}
        near = [any(tuple(c + o) in active for o in np.ndindex(2, 2, 2))
                for c in voxel - 1]
        assert np.mean(near) == 1.0
        # Rescaled as read_mesh does (inside [-0.5, 0.5], as it asserts), the mesh is larger
        # than the grid's surface by the factor the export warns of (a 3-cell margin kept).
        lo, hi = v.min(0), v.max(0)
        assert abs((hi - lo).max() - (T2_RES - 6) / T2_RES) < 1.0 / T2_RES
        rescaled = (v - (lo + hi) / 2) * (0.99999 / (hi - lo).max())
        assert np.all(np.abs(rescaled) <= 0.5)


def trellis2_span(size):
    """The `object_span` of a job at `size + 6` that TRELLIS.2 sees in a grid of `size`
    (docs/FORMAT.md: 0.99999 of the grid less 1 voxel at each end)."""
    return (0.99999 * size - 2.0) / (size + 6)


@pytest.fixture(scope="module")
def trellis2_exact(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("trellis2_exact")
    job, records = make_job(tmp, T2_RES + 6, "[params]\nobject_span = %.7f\n"
                            % trellis2_span(T2_RES), extra=[("open_box.off", OPEN_BOX)])
    out = tmp / "out"
    r = run("export", job, "--format", "trellis2", "--out", out)
    assert "warning" not in r.stderr, r.stderr
    return out, records


def trellis2_output_span(size):
    """The `output_span` `--for trellis2@size` sets: the output's box 0.99999 of TRELLIS.2's
    grid, in a job at `size + 6` (docs/FORMAT.md)."""
    return 0.99999 * size / (size + 6)


def test_trellis2_preset_gives_its_grid_exactly_with_its_span_to_the_last_digit(tmp_path):
    """issue 47: a job with the span the export advised, written with all its digits, was
    refused by every `run` (job.json read it back 1 ulp off); `--for trellis2@G` sets it."""
    span = trellis2_output_span(T2_RES)
    job, records = make_job(tmp_path, T2_RES + 6, "[params]\noutput_span = %r\n" % span)
    assert json.loads((job / "job.json").read_text())["config"]["params"]["output_span"] == span
    by_preset = tmp_path / "preset"
    by_preset.mkdir()
    job2, _ = make_job(by_preset, preset="trellis2@%d" % T2_RES)
    file2 = json.loads((job2 / "job.json").read_text())
    assert file2["config"]["preset"] == "trellis2@%d" % T2_RES
    assert file2["fingerprint"] == json.loads((job / "job.json").read_text())["fingerprint"]
    out = tmp_path / "out"
    r = run("export", job2, "--format", "trellis2", "--out", out)
    assert "warning" not in r.stderr, r.stderr
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    assert root["dual_grid"].endswith("dual_grid_%d" % T2_RES)
    assert sorted(filter_metadata(root)) == sorted(r["sha256"] for r in records)


def test_trellis2_names_items_of_a_manifest_of_ids_by_their_sha256(tmp_path):
    """issue 41, defect 7: a job with its own ids (no sha256 column) had its files named by the
    export stem, which was also written into metadata.csv's `sha256` column."""
    import hashlib

    manifest = tmp_path / "ids.csv"
    names = {"chair/1": "cube.off", "椅子": "wuson.stl"}
    manifest.write_text("id,uri\n" + "".join(
        "%s,%s\n" % (i, ROOT / "examples" / n) for i, n in names.items()), encoding="utf-8")
    job = tmp_path / "job"
    run("init", job, "--manifest", manifest, "--resolution", 32)
    run("run", job, "--workers", "1")
    out = tmp_path / "out"
    run("export", job, "--format", "trellis2", "--frame", "normalized", "--out", out)
    shas = {hashlib.sha256((ROOT / "examples" / n).read_bytes()).hexdigest(): i
            for i, n in names.items()}
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    assert sorted(filter_metadata(root)) == sorted(shas)
    for sha in shas:
        assert (pathlib_join(root["dual_grid"], sha + ".vxz")).is_file()
        assert (pathlib_join(root["mesh_dump"], sha + ".pickle")).is_file()
    import csv
    with open(out / "metadata.csv", newline="", encoding="utf-8") as f:
        rows = {r["sha256"]: r["id"] for r in csv.DictReader(f)}
    assert rows == shas


def test_trellis2_job_in_its_frame_exports_its_grid_exactly(trellis2_exact):
    out, records = trellis2_exact
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    assert root["dual_grid"].endswith("dual_grid_%d" % T2_RES)
    for rec in records:
        v, f, coords, attrs, _ = load_item(root, rec["sha256"])
        assert coords.min() >= 0 and coords.max() < T2_RES
        assert coords.min() <= 1 and coords.max() >= T2_RES - 2  # the object spans the grid
        # As read_mesh places it (the longest side scaled to 0.99999, centred), the dump moves
        # by little more than the voxel of room left at each end for shells (less for the
        # open box, whose shell fills it), the normalization's sub-voxel shift and marching
        # cubes cutting the tips (a job in its own frame: 3 voxels at 256, above).
        lo, hi = v.min(0), v.max(0)
        rescaled = (v - (lo + hi) / 2) * (0.99999 / (hi - lo).max())
        assert np.abs(rescaled).max() <= 0.5
        moved = np.abs(rescaled - v).max() * T2_RES
        assert moved < (0.5 if "open_box" in rec["uri"] else 1.3), (rec["uri"], moved)
        # And the dual vertices lie on it as read, up to that move.
        from scipy.spatial import cKDTree
        dual = (coords + attrs["vertices"] / 255.0) / T2_RES - 0.5
        d, _ = cKDTree(rescaled).query(dual)
        assert d.max() * T2_RES < np.sqrt(3) + moved, (rec["uri"], d.max() * T2_RES)


def crossed_flags(v, f, size):
    """TRELLIS.2's `intersected` of the mesh `v`, `f` (in its aabb frame [-0.5, 0.5]^3 at grid
    `size`), as `o-voxel/src/convert/flexible_dual_grid.cpp` `intersect_qef` sets it: for each
    axis a, the voxel (i, j, int(z)) whose a-edge at its upper corner in the other two axes
    (the grid line at i + 1, j + 1 of those axes; lines 1..size) a triangle crosses at z.
    Returns {(x, y, z, axis)}; triangles seen edge-on along a are skipped (they cross no line
    but at their border, where a neighbour crosses it)."""
    tri = ((np.asarray(v, np.float64) + 0.5) * size)[np.asarray(f)]
    out = set()
    for a2 in range(3):
        a0, a1 = (a2 + 1) % 3, (a2 + 2) % 3
        p, z = tri[:, :, [a0, a1]], tri[:, :, a2]
        lo = np.ceil(p.min(1) - 1e-9).astype(np.int64)
        hi = np.floor(p.max(1) + 1e-9).astype(np.int64)
        k = int((hi - lo).max()) + 1
        for dx, dy in np.ndindex(k, k):
            line = lo + [dx, dy]
            cand = np.flatnonzero((line <= hi).all(1))
            q, t, zz = line[cand].astype(np.float64), p[cand], z[cand]
            e1, e2, d = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], q - t[:, 0]
            det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
            ok = np.abs(det) > 1e-12
            det = np.where(ok, det, 1.0)
            b1 = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
            b2 = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
            eps = 1e-6
            hit = ok & (b1 >= -eps) & (b2 >= -eps) & (b1 + b2 <= 1 + eps)
            zc = (1 - b1 - b2) * zz[:, 0] + b1 * zz[:, 1] + b2 * zz[:, 2]
            for (x, y), zv in zip(line[cand][hit], zc[hit]):
                c = [0, 0, 0]
                c[a0], c[a1], c[a2] = int(x) - 1, int(y) - 1, int(np.floor(zv))
                if 1 <= x <= size and 1 <= y <= size and 0 <= c[a2] < size:
                    out.add((*c, a2))
    return out


def written_flags(coords, intersected):
    """Our `intersected` bits as {(x, y, z, axis)}."""
    bits = intersected.reshape(-1)
    return {(*map(int, c), a) for c, b in zip(coords, bits) for a in range(3) if b >> a & 1}


def flag_disagreement(ours, theirs):
    """(share of our flags no triangle crosses, share of crossed edges we do not flag)."""
    return len(ours - theirs) / max(len(ours), 1), len(theirs - ours) / max(len(theirs), 1)


def test_trellis2_intersected_is_what_its_own_conversion_sets_on_the_mesh_dump(trellis2_exact):
    """Our bits (phi changes sign along the edge) against TRELLIS.2's rule (a triangle crosses
    the edge) applied to the surface the dual vertices describe: the mesh dump, in the grid's
    frame. On our watertight output each edge with a sign change is crossed once and no other
    edge is crossed, so the two meanings coincide (docs/FORMAT.md, "What does not match")."""
    out, records = trellis2_exact
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    for rec in records:
        v, f, coords, attrs, _ = load_item(root, rec["sha256"])
        ours = written_flags(coords, attrs["intersected"])
        theirs = crossed_flags(v, f, T2_RES)
        flagged_not_crossed, crossed_not_flagged = flag_disagreement(ours, theirs)
        assert flagged_not_crossed < 1e-3 and crossed_not_flagged < 1e-3, (
            rec["uri"], flagged_not_crossed, crossed_not_flagged)


# A closed plate 1 % as thick as wide (thin) and a wavy open sheet, beside the open box.
THIN_PLATE = """OFF
8 12 0
0 0 0
1 0 0
1 0.6 0
0 0.6 0
0 0 0.01
1 0 0.01
1 0.6 0.01
0 0.6 0.01
3 0 2 1
3 0 3 2
3 4 5 6
3 4 6 7
3 0 1 5
3 0 5 4
3 1 2 6
3 1 6 5
3 2 3 7
3 2 7 6
3 3 0 4
3 3 4 7
"""


def wavy_sheet(n=24):
    """An open sheet z = 0.1 sin(6u) cos(4w) over the unit square, as OBJ text."""
    u, w = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    v = np.stack([u, w, 0.1 * np.sin(6 * u) * np.cos(4 * w)], -1).reshape(-1, 3)
    lines = ["v %.9g %.9g %.9g" % tuple(p) for p in v]
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j + 1, (i + 1) * n + j + 1, (i + 1) * n + j + 2, i * n + j + 2
            lines += ["f %d %d %d" % (a, b, c), "f %d %d %d" % (a, c, d)]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def trellis2_framed(tmp_path_factory):
    """A job made with `--for trellis2@48`: closed (cube, wuson), thin (the plate) and open
    (the box without its top, the sheet) sources."""
    tmp = tmp_path_factory.mktemp("trellis2_framed")
    job, records = make_job(tmp, preset="trellis2@%d" % T2_RES, extra=[
        ("open_box.off", OPEN_BOX), ("plate.off", THIN_PLATE), ("sheet.obj", wavy_sheet())])
    out = tmp / "out"
    r = run("export", job, "--format", "trellis2", "--out", out)
    assert "warning" not in r.stderr, r.stderr
    return out, records


def read_mesh_f32(v):
    """`FlexiDualGridDataset.read_mesh`'s placement (`trellis2/datasets/flexi_dual_grid.py`,
    as `data_toolkit/dual_grid.py` L50-55) in float32 as torch computes it: the box centre
    `(min + max) / 2`, the scale `0.99999 / side` (torch's `Tensor.__rtruediv__`:
    `side.reciprocal() * 0.99999`), then `(v - centre) * scale`."""
    v = np.asarray(v, np.float32)
    lo, hi = v.min(0), v.max(0)
    centre = (lo + hi) / np.float32(2)
    side = (hi - lo).max()
    scale = (np.float32(1) / side) * np.float32(0.99999)
    return (v - centre) * scale, centre, scale


def test_trellis2_preset_dual_grid_is_the_grid_of_the_mesh_read_mesh_returns(trellis2_framed):
    """issue 62 item 1: on the mesh `read_mesh` returns (not the dump as written), TRELLIS.2's
    crossing rule sets exactly our `intersected` bits, and every dual vertex lies in its
    voxel; the dump's box is where `read_mesh` puts it, so it moves nothing."""
    out, records = trellis2_framed
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    assert sorted(filter_metadata(root)) == sorted(r["sha256"] for r in records)
    for rec in records:
        v, f, coords, attrs, _ = load_item(root, rec["sha256"])
        read, centre, scale = read_mesh_f32(v)
        assert np.all(centre == 0) and scale == 1, (rec["uri"], centre, scale)
        assert np.array_equal(read, v), rec["uri"]
        assert np.abs(read).max() <= 0.5
        lo, hi = read.min(0), read.max(0)
        assert (hi - lo).max() == np.float32(0.99999), rec["uri"]  # fills the cube
        ours = written_flags(coords, attrs["intersected"])
        theirs = crossed_flags(read, f, T2_RES)
        assert ours == theirs, (rec["uri"], len(ours - theirs), len(theirs - ours))
        # Each dual vertex, placed against the mesh as read, within its voxel (to 1/255).
        dual = (coords + attrs["vertices"] / 255.0) / T2_RES - 0.5
        local = ((dual - centre) * scale + 0.5) * T2_RES - coords
        assert local.min() >= -1 / 255 and local.max() <= 1 + 1 / 255, rec["uri"]


def test_trellis2_filter_drops_items_over_the_limits(trellis2):
    out, _ = trellis2
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    sizes = [int(r["dual_grid_size"]) for r in filter_metadata(root).values()]
    assert len(filter_metadata(root, max_active_voxels=min(sizes))) == 1
    assert len(filter_metadata(root, max_num_faces=0)) == 0


# --- Direct3D-S2 -------------------------------------------------------------------------------

def winding_number(points, v, f, chunk=64):
    """Generalised winding number of a triangle mesh at `points` (solid angles, Van Oosterom
    and Strackee), ≈1 inside a closed outward mesh and ≈0 outside."""
    tri = v[f]
    out = np.empty(len(points))
    for lo in range(0, len(points), chunk):
        p = points[lo:lo + chunk, None, None, :]
        a, b, c = (tri[None, :, k, :] - p[:, :, 0, :] for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("ijk,ijk->ij", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ijk,ijk->ij", a, b) * lc
               + np.einsum("ijk,ijk->ij", b, c) * la + np.einsum("ijk,ijk->ij", c, a) * lb)
        out[lo:lo + chunk] = np.arctan2(det, den).sum(1) / (2 * np.pi)
    return out


@pytest.fixture(scope="module")
def direct3d(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("direct3d")
    job, _ = make_job(tmp, D3_RES, preset="direct3d-s2")  # object_span = 0.95
    out = tmp / "out"
    run("export", job, "--format", "direct3d-s2", "--out", out)
    return job, out


def test_direct3d_s2_needs_the_span_of_its_cube(tmp_path):
    job, _ = make_job(tmp_path, 32)
    r = run("export", job, "--format", "direct3d-s2", "--out", tmp_path / "o", check=False)
    assert r.returncode == 2 and "params.object_span = 0.95" in r.stderr, r.stderr
    assert "--for direct3d-s2" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()
    run("export", job, "--format", "direct3d-s2", "--frame", "normalized", "--out", tmp_path / "o")


def test_direct3d_s2_indices_frame_and_signs(direct3d):
    job, out = direct3d
    items = list(reader.iter_export(out))
    assert len(items) == len(MESHES)
    batch = reader.collate_direct3d_s2(items)  # SparseSDFVAE.encode's batch keys
    assert batch["sparse_sdf"].shape[1] == 1 and batch["sparse_index"].shape[1] == 3
    for it in items:
        res = int(it["resolution"])
        idx = np.asarray(it["sparse_index"], np.int64)
        sdf = np.asarray(it["sparse_sdf"], np.float32).reshape(-1)
        # sparse2mesh: grid[idx] = sdf in a res³ grid, so every index is in [0, res).
        assert idx.min() >= 0 and idx.max() < res
        assert len(np.unique(idx, axis=0)) == len(idx)
        assert np.all(np.abs(sdf) <= 1)
        # Frame: grid point i at 2i/res - 1; the object's longest side on ±0.95.
        inside = idx[sdf < 0] * 2.0 / res - 1
        extent = (inside.max(0) - inside.min(0)).max()
        assert abs(extent - 1.9) < 4.0 / res, extent
        # Signs: positive outside, as the winding number of the watertight mesh says, for the
        # points farther than a voxel (|sdf| > 1/4 of the 4-voxel band).
        mesh_path = out.parent / ("%s.ply" % it["item_index"])
        run("show", job, "--id", it["id"], "-o", mesh_path)
        import trimesh
        m = trimesh.load(mesh_path, process=False)
        far = np.flatnonzero(np.abs(sdf) > 0.25)
        pick = np.random.default_rng(0).choice(far, size=min(300, len(far)), replace=False)
        center, scale = np.asarray(it["center"]), float(it["scale"])
        src = (idx[pick] / res - 0.5) / scale + center  # source frame of `show`
        w = winding_number(src, np.asarray(m.vertices, np.float64), np.asarray(m.faces))
        np.testing.assert_array_equal(w > 0.5, sdf[pick] < 0)
