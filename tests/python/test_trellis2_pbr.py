"""TRELLIS.2's PBR voxels (`export --format trellis2` of a job with `[attributes]`) read back the
way its texture VAE's dataset reads them: `trellis2/datasets/sparse_voxel_pbr.py`
`SparseVoxelPbrDataset` (`filter_metadata` L145-158, `read_pbr_voxel` L255-262, with the
texture VAE config's `with_mesh: false` and `attrs` base_color, metallic, roughness, alpha) over
the folders of `data_dir.json` (`trellis2/datasets/components.py` `StandardDatasetBase`), the
`.vxz` decoded by a reader written from its description (docs/FORMAT.md). The voxels must be
the dual grid's exactly (`structured_latent_svpbr.py` L249 asserts that the shape and material
latents share their coordinates) and the values the shard's attribute columns."""

import csv
import json
import pathlib
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

G = 32
FREE_CELLS = 3  # voxel i of the export is cell i + 3 of a job made with --for trellis2@G
ATTRS = {"base_color": 3, "metallic": 1, "roughness": 1, "alpha": 1}  # the config's `attrs`

# A tetrahedron with one colour per face (OFF face colours, 0-255, read as sRGB).
COLOURED_TETRA = """OFF
4 4 0
0 0 0
1 0 0
0 1 0
0 0 1
3 0 2 1 200 30 30
3 0 1 3 30 200 30
3 0 3 2 30 30 200
3 1 2 3 240 240 240
"""


def make_job(tmp, config):
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in ["box_textured.glb", "cube.off"]:
        (meshes / name).write_bytes((ROOT / "examples" / name).read_bytes())
    (meshes / "tetra.off").write_text(COLOURED_TETRA)
    manifest = tmp / "m.jsonl"
    run("manifest", "build", meshes, "-o", manifest)
    (tmp / "job.toml").write_text(config)
    job = tmp / "job"
    run("init", job, "--manifest", manifest, "--config", tmp / "job.toml",
        "--for", "trellis2@%d" % G)
    run("run", job, "--workers", "1")
    return job, [json.loads(line) for line in manifest.read_text().splitlines()]


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("trellis2_pbr")
    job, records = make_job(tmp, "[attributes]\nenabled = true\n")
    out = tmp / "out"
    r = run("export", job, "--format", "trellis2", "--out", out)
    assert "warning" not in r.stderr and "pbr_voxels" not in r.stderr, r.stderr
    (root,) = json.loads((out / "data_dir.json").read_text()).values()
    return job, records, root


def combined_metadata(root):
    """`StandardDatasetBase.__init__` for a `data_dir` object: one metadata.csv per listed
    folder, combined on sha256 (with the csv module; pandas, which upstream uses, reads the
    literal `True` as a boolean and the counts as numbers)."""
    rows = {}
    for folder in root.values():
        with open(pathlib.Path(folder) / "metadata.csv", newline="") as f:
            for row in csv.DictReader(f):
                rows.setdefault(row["sha256"], {}).update(row)
    return rows


def filter_pbr_metadata(metadata, max_active_voxels=1_000_000, max_num_faces=None):
    """`SparseVoxelPbrDataset.filter_metadata` with `min_aesthetic_score=None` (we do not know
    the score; docs/FORMAT.md)."""
    return {sha: r for sha, r in metadata.items()
            if r.get("pbr_voxelized") == "True"
            and int(r["num_pbr_voxels"]) <= max_active_voxels
            and (max_num_faces is None or int(r["num_faces"]) <= max_num_faces)}


def read_pbr_voxel(folder, sha):
    """`SparseVoxelPbrDataset.read_pbr_voxel`: the attributes by name in `attrs` order, each
    byte b as b / 255 · 2 − 1; the coordinates as read."""
    coords, attr, header = read_vxz(pathlib.Path(folder) / (sha + ".vxz"))
    feats = np.concatenate([attr[k] for k in ATTRS], axis=1) / 255.0 * 2 - 1
    return coords, feats, attr, header


def test_pbr_folder_is_listed_with_its_metadata_and_every_item_loads(export):
    _, records, root = export
    assert root["pbr_voxel"].endswith("pbr_voxels_%d" % G)
    assert root["dual_grid"].endswith("dual_grid_%d" % G)
    metadata = combined_metadata(root)
    kept = filter_pbr_metadata(metadata, max_num_faces=1_000_000)
    assert sorted(kept) == sorted(r["sha256"] for r in records)
    for sha, row in kept.items():
        # `self.loads`: the voxel count per instance, which is the dual grid's.
        assert row["num_pbr_voxels"] == row["dual_grid_size"]
        _, feats, _, header = read_pbr_voxel(root["pbr_voxel"], sha)
        assert header["attr"] == [[k, c] for k, c in ATTRS.items()]
        assert header["num_voxel"] == int(row["num_pbr_voxels"])
        assert feats.shape == (header["num_voxel"], 6)
        assert feats.min() >= -1 and feats.max() <= 1


def test_pbr_voxels_are_the_dual_grid_voxels_with_the_shard_values(export):
    job, records, root = export
    sha_of = {r["uri"]: r["sha256"] for r in records}
    seen = set()
    for item in reader.iter_items(job):
        sha = sha_of[item["uri"]]
        coords, _, attr, _ = read_pbr_voxel(root["pbr_voxel"], sha)
        dual, _, _ = read_vxz(pathlib.Path(root["dual_grid"]) / (sha + ".vxz"))
        # The same voxels in the same order (the latents' coordinates then agree).
        np.testing.assert_array_equal(coords, dual)
        row = {tuple(c): i for i, c in enumerate(item["cells"].astype(np.int64) - FREE_CELLS)}
        rows = np.array([row[tuple(c)] for c in coords])
        np.testing.assert_array_equal(attr["base_color"], item["base_color"][rows])
        for name in ("metallic", "roughness", "alpha"):
            np.testing.assert_array_equal(attr[name][:, 0], item[name][rows])
        seen.add(item["uri"].rsplit("/", 1)[-1])
    assert seen == {"box_textured.glb", "cube.off", "tetra.off"}


def test_each_source_keeps_its_colours(export):
    job, records, root = export
    by_name = {r["uri"].rsplit("/", 1)[-1]: r["sha256"] for r in records}
    colours = {name: read_pbr_voxel(root["pbr_voxel"], sha)[2]["base_color"]
               for name, sha in by_name.items()}
    # No material: the default, 0.8 linear grey (sRGB byte 231).
    np.testing.assert_array_equal(np.unique(colours["cube.off"], axis=0), [[231, 231, 231]])
    assert len(np.unique(colours["box_textured.glb"], axis=0)) > 10  # textured
    # Every face colour of the tetrahedron is some voxel's colour.
    tetra = {tuple(c) for c in colours["tetra.off"]}
    for face in [(200, 30, 30), (30, 200, 30), (30, 30, 200), (240, 240, 240)]:
        assert face in tetra, face
