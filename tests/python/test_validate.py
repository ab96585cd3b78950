"""`sparc3d validate` (pymeshlab checks of a sample of a job's outputs) and the shared item
sampler of `validate` and `eval JOB --sample`."""

import json
import os
import shutil
import subprocess
import sys

import pytest

pymeshlab = pytest.importorskip("pymeshlab")

from sparc3d_cli import ROOT, run as run_cli
VALIDATE_PY = ROOT / "pipeline" / "validate" / "validate.py"
MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
CHECKS = {"watertight", "manifold", "oriented", "volume", "components", "hausdorff"}


def env(**extra):
    e = dict(os.environ, SPARC3D_PYTHON=sys.executable)
    e.update(extra)
    return e


def run(*args, check=True, **extra):
    return run_cli(*args, check=check, env=env(**extra))


def make_job(tmp, name, shard_size, workers):
    meshes = tmp / "meshes"
    if not meshes.exists():
        meshes.mkdir()
        for m in MESHES:
            shutil.copy(ROOT / "examples" / m, meshes / m)
        (meshes / "broken.obj").write_text("not a mesh\n")
        run("manifest", "build", meshes, "-o", tmp / "m.jsonl")
    job = tmp / name
    run("init", job, "--manifest", tmp / "m.jsonl", "--resolution", 64, "--shard-size", shard_size)
    run("run", job, "--workers", workers)
    return job


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("validate")
    return make_job(tmp, "job", 16, 1), make_job(tmp, "job2", 2, 2)


def report_rows(job):
    return [json.loads(l) for l in (job / "validation" / "report.jsonl").read_text().splitlines()]


def test_every_check_passes_on_a_small_job(jobs):
    job = jobs[0]
    r = run("validate", job, "--sample", "100%", "--json")
    summary = json.loads(r.stdout)
    assert summary["checked"] == summary["population"] == len(MESHES)
    assert summary["passed"] == len(MESHES) and summary["failed"] == 0
    rows = report_rows(job)
    assert len(rows) == len(MESHES)
    for row in rows:
        assert row["ok"] is True, row
        assert set(row["checks"]) == CHECKS and all(row["checks"].values()), row
        m = row["measures"]
        assert m["boundary_edges"] == 0 and m["non_two_manifold_edges"] == 0
        assert m["non_two_manifold_vertices"] == 0 and m["inconsistent_edges"] == 0
        assert m["volume"] > 0 and m["components"] >= 1
        assert 0 <= m["hausdorff_voxels"] <= 3
    md = (job / "validation" / "summary.md").read_text()
    assert f"{len(MESHES)} passed, 0 failed" in md
    assert not (job / "validation" / "work").exists()


def test_sample_is_reproducible_and_independent_of_workers_and_shards(jobs):
    job, job2 = jobs
    picked = []
    for j in (job, job2, job):
        run("validate", j, "--sample", "2", "--seed", "7")
        picked.append(sorted(r["id"] for r in report_rows(j)))
    assert len(picked[0]) == 2
    assert picked[0] == picked[1] == picked[2]
    run("validate", job, "--sample", "40%", "--seed", "7")  # ceil(0.4 * 5) = 2: the same items
    assert sorted(r["id"] for r in report_rows(job)) == picked[0]
    # eval JOB --sample uses the same sampler.
    e = json.loads(run("eval", job, "--sample", "2", "--sample-seed", "7",
                       "--samples", "20000", "--json").stdout)
    assert sorted(i["id"] for i in e["items"]) == picked[0]
    assert e["evaluated"] == 2 and e["errors"] == 0
    for i in e["items"]:
        assert i["report"]["options"]["resolution"] == 64
        assert i["report"]["output_closed"] is True
    assert e["median"]["cd_voxels"] is not None and e["median"]["anc"] > 80


def test_a_failed_check_gives_a_nonzero_exit(jobs):
    job = jobs[0]
    r = run("validate", job, "--sample", "1", "--max-hausdorff-voxels", "0", check=False)
    assert r.returncode == 1, r.stderr
    assert "FAIL" in r.stderr and "hausdorff" in r.stderr
    md = (job / "validation" / "summary.md").read_text()
    assert "## Failures" in md and "0 passed, 1 failed" in md


def test_missing_pymeshlab_names_the_install_command(jobs):
    r = run("validate", jobs[0], check=False, SPARC3D_PYTHON="/bin/false")
    assert r.returncode == 2
    assert "python3 -m pip install -r pipeline/validate/requirements.txt" in r.stderr


def ask(requests):
    """Runs validate.py on JSON requests; returns its answers."""
    text = "".join(json.dumps(q) + "\n" for q in requests)
    r = subprocess.run([sys.executable, str(VALIDATE_PY)], input=text, capture_output=True,
                       text=True, check=True)
    return [json.loads(l) for l in r.stdout.splitlines()]


def save(path, v, f):
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f))
    ms.save_current_mesh(str(path))


def test_validator_catches_broken_meshes(tmp_path):
    good = tmp_path / "good.ply"
    run("convert", ROOT / "examples" / "sphere.obj", "-o", good, "--resolution", 32)
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(good))
    v, f = ms.current_mesh().vertex_matrix(), ms.current_mesh().face_matrix()
    holed, flipped, inverted = tmp_path / "holed.ply", tmp_path / "flipped.ply", tmp_path / "inv.ply"
    save(holed, v, f[1:])                                     # one face removed
    g = f.copy()
    g[0] = g[0][::-1]
    save(flipped, v, g)                                       # one face turned over
    save(inverted, v, f[:, ::-1].copy())                      # every face turned inwards
    src = str(ROOT / "examples" / "sphere.obj")
    answers = ask([
        {"id": "good", "output": str(good), "source": src, "voxel": 0.05, "max_hausdorff_voxels": 3},
        {"id": "holed", "output": str(holed), "source": src, "voxel": 0.05, "max_hausdorff_voxels": 3},
        {"id": "flipped", "output": str(flipped)},
        {"id": "inverted", "output": str(inverted)},
        {"id": "missing", "output": str(tmp_path / "nope.ply")},
    ])
    by = {a["id"]: a for a in answers}
    assert by["good"]["ok"] is True, by["good"]
    h = by["holed"]
    assert h["ok"] is False and h["checks"]["watertight"] is False
    assert h["measures"]["boundary_edges"] == 3
    assert h["checks"]["volume"] is False  # no volume for an open mesh
    fl = by["flipped"]
    assert fl["ok"] is False and fl["checks"]["oriented"] is False
    assert fl["measures"]["inconsistent_edges"] == 3
    inv = by["inverted"]
    assert inv["checks"]["oriented"] is True and inv["checks"]["volume"] is False
    assert inv["measures"]["volume"] < 0
    assert by["missing"]["ok"] is False and by["missing"]["error"]


def test_probe_reports_versions():
    r = subprocess.run([sys.executable, str(VALIDATE_PY), "--probe"], capture_output=True,
                       text=True, check=True)
    v = json.loads(r.stdout)
    assert v["pymeshlab"] and v["python"]


def test_run_validates_a_sample_when_asked(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for m in ["sphere.obj", "cube.off"]:
        shutil.copy(ROOT / "examples" / m, meshes / m)
    run("manifest", "build", meshes, "-o", tmp_path / "m.jsonl")
    job = tmp_path / "job"
    run("init", job, "--manifest", tmp_path / "m.jsonl", "--resolution", 32)
    r = run("run", job, "--workers", 1, "--validate-sample", "1%")
    assert "1 of 1 passed" in r.stderr, r.stderr
    assert len(report_rows(job)) == 1  # ceil(1% of 2) = 1
    assert (job / "validation" / "summary.md").exists()
