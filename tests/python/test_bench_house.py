"""The benchmark house (ops/bench/README.md): every script there and in vae/bench/ starts (its
imports, the shared helper among them, resolve from where it lives), the shared helper finds
the binary and keeps results as data, and one benchmark records a real run."""

import json
import os
import py_compile
import subprocess
import sys

import pytest
from sparc3d_cli import ROOT, sparc3d_bin

BENCH = ROOT / "ops" / "bench"
sys.path.insert(0, str(BENCH))
import benchlib  # noqa: E402

# Scripts that cannot start here, each with the reason; they are compiled instead.
NOT_STARTED = {
    "renders_vs_blender.py": "runs inside Blender (`blender --python`), which imports bpy",
    "section_plot.py": "needs matplotlib, which the tests do not install",
}
SCRIPTS = sorted(p for p in [*BENCH.glob("*.py"), *(ROOT / "vae" / "bench").glob("*.py")]
                 if p.name != "benchlib.py")


def script_env(**extra):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "python"), str(ROOT / "vae"),
                                         env.get("PYTHONPATH", "")])
    env.update(extra)
    return env


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: f"{p.parent.parent.name}/{p.name}")
def test_every_benchmark_script_starts(script):
    if script.name in NOT_STARTED:
        py_compile.compile(str(script), doraise=True)
        return
    r = subprocess.run([sys.executable, str(script), "--help"], capture_output=True, text=True,
                       env=script_env(), timeout=300)
    assert r.returncode == 0, r.stderr
    assert "usage:" in r.stdout


def test_the_scripts_not_started_are_still_there():
    names = {p.name for p in SCRIPTS}
    assert set(NOT_STARTED) <= names


def test_binary_prefers_the_flag_then_the_environment(tmp_path, monkeypatch):
    exe = tmp_path / "sparc3d-here"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    monkeypatch.setenv("SPARC3D_BIN", "/bin/true")
    assert benchlib.binary(str(exe)) == str(exe)
    assert benchlib.binary() == "/bin/true"


def test_a_binary_that_is_not_there_is_an_error_not_a_fallback(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SPARC3D_BIN", "/bin/true")
    with pytest.raises(SystemExit) as exit_:
        benchlib.binary(str(tmp_path / "missing"))
    assert exit_.value.code == 2
    assert "--bin" in capsys.readouterr().err


def test_last_json_returns_failures_instead_of_raising():
    ok, seconds, err = benchlib.last_json(
        [sys.executable, "-c", "print('progress'); print('{\"a\": 1}'); print('done')"])
    assert (ok, err) == ({"a": 1}, None) and seconds >= 0
    none, _, err = benchlib.last_json([sys.executable, "-c", "import sys; sys.exit(3)"])
    assert none is None and err.startswith("exit 3")
    empty, _, err = benchlib.last_json([sys.executable, "-c", "pass"], json_optional=True)
    assert (empty, err) == ({}, None)


def test_results_are_kept_only_when_recording(tmp_path):
    benchlib.Results("nothing", None, runs=tmp_path).add({"x": 1})
    assert list(tmp_path.iterdir()) == []
    results = benchlib.Results("demo", "test-machine", runs=tmp_path)
    results.add({"b": 2, "a": 1})
    results.add({"a": 3})
    (folder,) = tmp_path.iterdir()
    assert folder.name.endswith("-test-machine")
    lines = (folder / "demo.jsonl").read_text().splitlines()
    assert [json.loads(line) for line in lines] == [{"a": 1, "b": 2}, {"a": 3}]
    facts = json.loads((folder / "machine.json").read_text())
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True)
    assert facts["cores"] == os.cpu_count()
    assert facts["commit"] == (head.stdout.strip() if head.returncode == 0 else None)


def test_thread_scaling_records_a_real_run(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "wuson.stl").symlink_to(ROOT / "examples" / "wuson.stl")
    runs = tmp_path / "runs"
    r = subprocess.run(
        [sys.executable, str(BENCH / "thread_scaling.py"), "--bin", sparc3d_bin(),
         "--meshes", str(meshes), "--resolution", "64", "--threads", "1,2", "--record", "ci"],
        capture_output=True, text=True, env=script_env(SPARC3D_BENCH_RUNS=str(runs)),
        timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("\n| 1 | 1 |") == 1 and "\n| 2 | 1 |" in r.stdout
    (folder,) = runs.iterdir()
    rows = [json.loads(line) for line in (folder / "thread_scaling.jsonl").read_text().splitlines()]
    assert [(row["threads"], row["meshes"], row["failed"]) for row in rows] == [(1, 1, 0),
                                                                               (2, 1, 0)]
    assert all(row["median_wall"] > 0 and row["resolution"] == 64 for row in rows)
    assert json.loads((folder / "machine.json").read_text())["binary"].startswith("sparc3d")
