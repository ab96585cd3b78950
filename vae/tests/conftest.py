"""Shared by the VAE tests: the checkout's packages (when not installed), the `sparc3d`
binary (found as tests/python finds it: `SPARC3D_BIN`, else the debug build under
`CARGO_TARGET_DIR` or `target/`), and small real jobs converted from the bundled examples."""

import pathlib
import shutil
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "python"))
for package, folder in (("sparc3d_reader", "python"), ("sparc3d_vae", "vae")):
    try:
        __import__(package)
    except ImportError:  # not installed (`pip install ./python ./vae`): use the checkout
        sys.path.insert(0, str(ROOT / folder))

from sparc3d_cli import run, sparc3d_bin  # noqa: E402

#: Two real meshes of different kinds: a closed sphere and an open, 51-part mesh.
MESHES = ["sphere.obj", "wuson.stl"]


def make_job(tmp, resolution, names=MESHES, deform=False, preset=None):
    """A converted job of the bundled example meshes at `resolution` (with the deformation
    stored when `deform`), or made for a consumer with `--for preset` (resolution None)."""
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in names:
        shutil.copy(ROOT / "examples" / name, meshes / name)
    run("manifest", "build", meshes, "-o", tmp / "m.jsonl")
    job = tmp / "job"
    config = tmp / "job.toml"
    config.write_text(f"[params]\ndeform = {'true' if deform else 'false'}\n")
    grid = ["--for", preset] if preset else ["--resolution", resolution]
    run("init", job, "--manifest", tmp / "m.jsonl", *grid, "--config", config)
    run("run", job, "--workers", 1)
    return job


@pytest.fixture(scope="session")
def job32(tmp_path_factory):
    """The two example meshes at 32³."""
    return make_job(tmp_path_factory.mktemp("job32"), 32)


@pytest.fixture(scope="session")
def binary():
    """Path of the sparc3d binary the VAE commands call."""
    return sparc3d_bin()
