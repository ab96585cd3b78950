"""TRELLIS.2's own code for the peer checks in this folder: where it is (a checkout, or the
folders a bare clone's HEAD holds, written out by `git archive`) and its files linked into a
package beside the stubs a check needs."""

import os
import subprocess
import sys


def trellis2_source(given, tmp, folders):
    """The folder holding TRELLIS.2's `folders` (`trellis2`, ...) and its commit: GIVEN itself
    (a checkout), or for a bare clone its HEAD's `folders` written under `tmp`."""
    git = ["git", "-C", str(given)]
    commit = subprocess.run(git + ["rev-parse", "HEAD"], capture_output=True, text=True)
    commit = commit.stdout.strip() if commit.returncode == 0 else "unknown"
    if (given / "trellis2").is_dir():
        return given, commit
    src = tmp / "trellis2-src"
    src.mkdir()
    tar = subprocess.run(git + ["archive", "HEAD", *folders], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(src)], input=tar.stdout, check=True)
    return src, commit


def linked_package(pkg, checkout, stubs, as_they_are, extra_paths=()):
    """`pkg` made of `stubs` (path → text) and `as_they_are` (path → path in `checkout`,
    linked), put first on `sys.path` with `extra_paths`."""
    for name, text in stubs.items():
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (pkg / name).write_text(text)
    for rel, src in as_they_are.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(checkout / src, pkg / rel)
    sys.path[:0] = [str(pkg), *map(str, extra_paths)]
