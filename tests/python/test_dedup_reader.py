"""The reader keeps one item per near-duplicate group from `sparc3d dedup --json`: a box and
its mirrored, scaled and moved copy are one group, a sphere and wuson are in none."""

import json
import shutil

import pytest

from sparc3d_cli import ROOT, run
from sparc3d_reader import dropped_ids, iter_items, one_per_group

CORNERS = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
FACES = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
         (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]


def write_box(path, scale, offset, mirror):
    """A 1 × 2 × 3 box, scaled, moved and optionally mirrored in x (faces turned back out)."""
    lines = []
    for x, y, z in CORNERS:
        p = ((-x if mirror else x) * 1.0, y * 2.0, z * 3.0)
        lines.append("v %g %g %g" % tuple(scale * c + o for c, o in zip(p, offset)))
    for a, b, c in FACES:
        lines.append("f %d %d %d" % ((a + 1, c + 1, b + 1) if mirror else (a + 1, b + 1, c + 1)))
    path.write_text("\n".join(lines) + "\n")


def test_one_item_per_group_from_the_dedup_result(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    write_box(meshes / "a_box.obj", 1.0, (0, 0, 0), False)
    write_box(meshes / "b_box_copy.obj", 2.5, (10, -4, 7), True)
    for name in ("sphere.obj", "wuson.stl"):
        shutil.copy(ROOT / "examples" / name, meshes / ("c_" + name))
    job = tmp_path / "job"
    run("run", meshes, "--job", job, "--resolution", 48, "--workers", 1)
    out = run("dedup", job, "--json").stdout
    result = json.loads(out)
    items = list(iter_items(job, samples=False))
    ids = {item["uri"].rsplit("/", 1)[-1]: item["id"] for item in items}
    assert len(result["groups"]) == 1, out
    assert result["groups"][0]["representative"]["id"] == ids["a_box.obj"]
    assert dropped_ids(result) == {ids["b_box_copy.obj"]}
    kept = [item["id"] for item in one_per_group(items, out)]
    assert kept == [item["id"] for item in items if item["id"] != ids["b_box_copy.obj"]]
    # The same result as bytes, as a file, and parsed.
    saved = tmp_path / "dedup.json"
    saved.write_text(out)
    assert dropped_ids(out.encode()) == dropped_ids(saved) == dropped_ids(str(saved))
    with pytest.raises(ValueError, match="sparc3d dedup --json"):
        dropped_ids({"groups": []})
