"""Appearance on the voxels, end to end: a job with `[attributes] enabled = true` stores
`base_color`, `metallic`, `roughness` and `alpha` (uint8, one row per row of `cells`) and the
per-item facts, the reader yields them under those names; the same job without the section
has none of these columns."""

import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader


def make_job(tmp, name, config_text):
    meshes = tmp / "meshes"
    if not meshes.exists():
        meshes.mkdir()
        for name_ in ["box_textured.glb", "cube.off"]:
            (meshes / name_).write_bytes((ROOT / "examples" / name_).read_bytes())
        # A vertex-coloured PLY: a tetrahedron, every corner pure green.
        (meshes / "green.ply").write_text(
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
            "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
            "0 0 0 0 255 0\n1 0 0 0 255 0\n0 1 0 0 255 0\n0 0 1 0 255 0\n"
            "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
        run("manifest", "build", meshes, "-o", tmp / "m.jsonl")
    config = tmp / (name + ".toml")
    config.write_text(config_text)
    path = tmp / name
    run("init", path, "--manifest", tmp / "m.jsonl", "--resolution", "32", "--config", config)
    run("run", path, "--workers", "1")
    return path


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("attributes")
    return (make_job(tmp, "with", "[attributes]\nenabled = true\n"),
            make_job(tmp, "without", "zstd_level = 3\n"))


def test_attribute_columns_are_stored_and_read_as_uint8_per_cell(jobs):
    with_job, _ = jobs
    items = {pathlib_name(it["uri"]): it for it in reader.iter_items(with_job)}
    assert set(items) == {"box_textured.glb", "cube.off", "green.ply"}
    for it in items.values():
        m = len(it["cells"])
        assert it["base_color"].shape == (m, 3) and it["base_color"].dtype == np.uint8
        for name in ("metallic", "roughness", "alpha"):
            assert it[name].shape == (m,) and it[name].dtype == np.uint8
    box = items["box_textured.glb"]
    assert box["appearance"]["textured"] and box["appearance"]["textures"] == 1
    assert box["appearance"]["alpha_modes"] == ["OPAQUE"]
    assert np.all(box["alpha"] == 255)
    # The OFF cube has no material: the default, 0.8 linear grey (sRGB 231), roughness 0.5.
    cube = items["cube.off"]
    assert np.all(cube["base_color"] == 231) and np.all(cube["roughness"] == 128)
    assert cube["appearance"]["materials"] == 0 and not cube["appearance"]["textured"]
    green = items["green.ply"]
    assert green["appearance"]["vertex_colors"]
    np.testing.assert_array_equal(np.unique(green["base_color"], axis=0), [[0, 255, 0]])


def test_a_job_without_the_section_has_no_attribute_columns(jobs):
    with_job, without_job = jobs
    names = pq.ParquetFile(without_job / "shards" / "part-00000.parquet").schema_arrow.names
    for name in reader.ATTRIBUTE_TENSORS + reader.APPEARANCE_COLUMNS:
        assert name not in names
    assert all("base_color" not in it for it in reader.iter_items(without_job))
    with_names = pq.ParquetFile(with_job / "shards" / "part-00000.parquet").schema_arrow.names
    assert set(with_names) - set(names) == set(
        reader.schema.ATTRIBUTE_COLUMNS)


def pathlib_name(uri):
    return uri.rsplit("/", 1)[-1]


def four_textured_box(folder, side):
    """A box OBJ whose twelve triangles use four materials, each mapping its own solid
    `side`² PNG (`t0.png` … `t3.png`, four colours)."""
    from PIL import Image
    folder.mkdir()
    colours = [(220, 20, 20), (20, 220, 20), (20, 20, 220), (220, 220, 20)]
    mtl = ""
    for i, c in enumerate(colours):
        Image.new("RGB", (side, side), c).save(folder / f"t{i}.png")
        mtl += f"newmtl m{i}\nKd 1 1 1\nmap_Kd t{i}.png\n"
    (folder / "box.mtl").write_text(mtl)
    corners = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    quads = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    text = "mtllib box.mtl\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in corners)
    text += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    for i, (a, b, c, d) in enumerate(quads):
        text += f"usemtl m{min(i, 3)}\nf {a}/1 {b}/2 {c}/3\nf {a}/1 {c}/3 {d}/4\n"
    (folder / "box.obj").write_text(text)
    return folder / "box.obj"


def test_textures_past_the_item_memory_budget_are_named_and_the_shape_kept(tmp_path):
    """Issue 64 item 4: an item decodes at most a quarter of `--item-memory` of texture
    (`sparcubes/src/materials/budget.rs`): at 1 GiB, 50,331,648 pixels, three 4096² maps
    of the box's four; the fourth is named in `appearance_not_read` and the row is `ok`.
    At the default 8 GiB all four are read."""
    obj = four_textured_box(tmp_path / "box", 4096)
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"path\n{obj}\n")
    config = tmp_path / "c.toml"
    config.write_text("[attributes]\nenabled = true\n")
    facts = {}
    for name, memory in [("small", ["--item-memory", "1G"]), ("default", [])]:
        job = tmp_path / name
        run("init", job, "--manifest", manifest, "--resolution", "32", "--config", config)
        run("run", job, "--workers", "1", *memory)
        rows = pq.read_table(next((job / "shards").glob("part-*.parquet"))).to_pylist()
        assert [r["status"] for r in rows] == ["ok"], rows[0].get("error")
        facts[name] = rows[0]
    small, default = facts["small"], facts["default"]
    assert small["textures"] == 3 and default["textures"] == 4
    assert "t3.png" in small["appearance_not_read"], small["appearance_not_read"]
    assert "texture budget" in small["appearance_not_read"]
    assert default["appearance_not_read"] == ""
    # The shape is the same either way.
    assert small["cells"] == default["cells"]
