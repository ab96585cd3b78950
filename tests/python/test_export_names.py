"""`sparc3d export` gives every item a file of its own, in every format: ids that map to the
same readable stem (`chair/1`, `chair 1`, `chair_1`; `椅子`, `桌子`), ids of any length (the
248–251-byte ones, and far longer ones), each
file naming its item inside (`id`, `item_index`), and an export replaces only an earlier
export, whole (docs/FORMAT.md, "Exports")."""

import json
import os
import sys

import numpy as np
import pytest

from sparc3d_cli import ROOT, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
# Ids whose readable stems collide, then ids around and far beyond the file-name limit
# (in bytes: 248..252 ASCII, 300 ASCII, 100 three-byte characters, 2000 ASCII).
IDS = (["chair/1", "chair 1", "chair_1", "椅子", "桌子"]
       + ["L" * n for n in (248, 249, 250, 251, 252, 300)]
       + ["长" * 100, "x" * 2000])
NAME_MAX = 255


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("export-names")
    manifest = tmp / "m.jsonl"
    with open(manifest, "w", encoding="utf-8") as f:
        for i, item_id in enumerate(IDS):
            uri = ROOT / "examples" / MESHES[i % len(MESHES)]
            f.write(json.dumps({"id": item_id, "uri": str(uri)}, ensure_ascii=False) + "\n")
    config = tmp / "job.toml"
    config.write_text("[samples]\nenabled = true\nsurface = 64\nsharp = 16\nnear = 64\n"
                      "sharp_near = 16\nvolume = 64\n")
    path = tmp / "job"
    run("init", path, "--manifest", manifest, "--resolution", 32, "--shard-size", 5,
        "--config", config)
    run("run", path, "--workers", 2)
    return path


@pytest.mark.parametrize("fmt", reader.EXPORT_FORMATS)
def test_every_item_gets_its_own_file_naming_it_inside(job, tmp_path, fmt):
    out = tmp_path / fmt
    # direct3d-s2's own frame needs object_span = 0.95 (too large a span for resolution 32).
    frame = ["--frame", "normalized"] if fmt == "direct3d-s2" else []
    r = run("export", job, "--format", fmt, "--out", out, *frame)
    assert f"{len(IDS)} items written" in r.stderr, r.stderr
    files = sorted(f for f in os.listdir(out) if f != ".sparc3d-export.json")
    assert len(files) == len(IDS), files  # no file shared, no temporary left behind
    assert all(f.endswith(".npz") and not f.startswith(".") for f in files), files
    # Unique also where a file system ignores case, and within the file-name limit.
    assert len({f.lower() for f in files}) == len(files)
    assert max(len(f.encode()) for f in files) <= NAME_MAX
    found = {}
    for f in files:
        with np.load(out / f) as z:
            found[str(z["id"])] = (int(z["item_index"]), f)
    assert sorted(found) == sorted(IDS)
    for i, item_id in enumerate(IDS):
        index, name = found[item_id]
        assert index == i and name.startswith("%06d-" % i), (item_id[:20], name)
    # The readable stem of a short id is the documented one.
    assert found["chair/1"][1] == "000000-chair_1.npz"
    assert found["椅子"][1] == "000003-__.npz"
    # The reader takes the id from inside the file, in manifest order.
    assert [it["id"] for it in reader.iter_export(out)] == IDS
    assert reader.ExportDataset(out)[3]["id"] == "椅子"


def test_an_export_folder_is_replaced_whole_and_any_other_folder_never(job, tmp_path):
    out = tmp_path / "out"
    run("export", job, "--format", "cubvh", "--out", out)
    before = {f: (out / f).read_bytes() for f in os.listdir(out)}
    assert ".sparc3d-export.json" in before
    # Exporting again replaces the earlier export whole: same names, same bytes, and a file
    # left in it by hand is gone with it; nothing is left beside it.
    (out / "stray.npz").write_bytes(b"left by hand")
    run("export", job, "--format", "cubvh", "--out", out, "--ids", IDS[0])
    after = sorted(f for f in os.listdir(out) if not f.startswith("."))
    assert after == ["000000-chair_1.npz"], after
    assert sorted(os.listdir(tmp_path)) == ["out"]
    # A folder that holds files and is no export is never written into: the error names it.
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my own notes")
    r = run("export", job, "--format", "cubvh", "--out", mine, check=False)
    assert r.returncode == 1 and "not an export" in r.stderr, r.stderr
    assert os.listdir(mine) == ["notes.txt"]
    assert sorted(os.listdir(tmp_path)) == ["mine", "out"]
