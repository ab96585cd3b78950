"""What the Python tests share: the repository root and running the built `sparc3d` binary
(`SPARC3D_BIN`, else the debug build under `CARGO_TARGET_DIR` or `target/`)."""

import os
import pathlib
import subprocess

ROOT = pathlib.Path(__file__).resolve().parents[2]


def sparc3d_bin():
    if os.environ.get("SPARC3D_BIN"):
        return os.environ["SPARC3D_BIN"]
    target = os.environ.get("CARGO_TARGET_DIR", str(ROOT / "target"))
    return str(pathlib.Path(target) / "debug" / "sparc3d")


def run(*args, check=True, env=None):
    """Runs `sparc3d ARGS` (any argument is passed through `str`) and returns the completed
    process with text stdout / stderr; with `check`, a non-zero exit fails the test and shows
    the command's stderr."""
    cmd = [sparc3d_bin(), *map(str, args)]
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if check:
        assert r.returncode == 0, "sparc3d %s failed (exit %d):\n%s" % (
            " ".join(cmd[1:]), r.returncode, r.stderr)
    return r
