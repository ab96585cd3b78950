"""`sparc3d report` opened in headless Chromium: the page loads without console errors, every
picture decodes, and a screenshot is kept as a test artefact
(`target/test-artefacts/report.png`).

Needs Debian's `chromium` (or `chromium-browser`, `google-chrome`); without it the test is
skipped, unless SPARC3D_CI=1 (set by CI: every test must run), which makes a missing browser a
failure. Only the standard library and pytest.

How pictures are checked: every `<img>` of the report carries `onload`/`onerror` attributes that
mark it `data-loaded` / `data-broken`; `--dump-dom` prints the DOM after the load event, so each
image must show `data-loaded`. Console messages are read from Chromium's log on stderr
(`--enable-logging=stderr`). A control page with a broken image checks that the harness does
catch one, and a page with a script error that it catches that.
"""

import os
import re
import shutil
import subprocess
import tempfile

import pytest

from sparc3d_cli import ROOT, run
ARTEFACTS = ROOT / "target" / "test-artefacts"


def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("SPARC3D_CI") == "1":
        pytest.fail("SPARC3D_CI=1 but no chromium on PATH (apt-get install -y chromium)")
    pytest.skip("chromium not installed (apt-get install -y chromium)")


def browse(page, *extra):
    """Opens a page in headless Chromium; returns (stdout, stderr)."""
    with tempfile.TemporaryDirectory(prefix="sparc3d-chromium-") as profile:
        cmd = [
            chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--user-data-dir=" + profile, "--enable-logging=stderr", "--v=0", *extra, page.as_uri(),
        ]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, "chromium failed (%d):\n%s" % (r.returncode, r.stderr[-3000:])
    return r.stdout, r.stderr


CONSOLE = re.compile(r"CONSOLE|Uncaught|Failed to load resource")


def problems(page):
    """Console messages and pictures that did not load, as a list of strings."""
    dom, log = browse(page, "--dump-dom")
    found = ["console: " + line for line in log.splitlines() if CONSOLE.search(line)]
    imgs = re.findall(r"<img\b[^>]*>", dom)
    for tag in imgs:
        # The attributes set by the handlers (the handlers' own text quotes them differently).
        if ' data-broken="1"' in tag or ' data-loaded="1"' not in tag:
            found.append("image not loaded: " + tag[:160])
    return found, len(imgs), dom


def test_harness_catches_a_broken_image(tmp_path):
    chromium()
    page = tmp_path / "broken.html"
    page.write_text(
        '<!DOCTYPE html><html><body><img src="data:image/png;base64,AAAA" alt="x" '
        "onload=\"this.setAttribute('data-loaded','1')\" onerror=\"this.setAttribute('data-broken','1')\">"
        "</body></html>"
    )
    found, n, _ = problems(page)
    assert n == 1
    assert any("image not loaded" in p for p in found), found


def test_harness_catches_a_console_error(tmp_path):
    chromium()
    page = tmp_path / "error.html"
    page.write_text("<!DOCTYPE html><html><body><script>no_such_function();</script></body></html>")
    found, _, _ = problems(page)
    assert any(p.startswith("console:") and "no_such_function" in p for p in found), found


def test_report_opens_in_chromium(tmp_path):
    browser = chromium()
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for name in sorted(os.listdir(ROOT / "examples")):
        if name.rsplit(".", 1)[-1].lower() in {"obj", "ply", "stl", "off", "glb", "gltf"}:
            shutil.copy(ROOT / "examples" / name, meshes / name)
    (meshes / "broken.obj").write_text("v 0 0 0\nf 1 2 3 <not a mesh>\n")
    manifest = tmp_path / "m.jsonl"
    run("manifest", "build", str(meshes), "-o", str(manifest))
    job = tmp_path / "job"
    run("init", str(job), "--manifest", str(manifest), "--resolution", "64")
    run("run", str(job), "--workers", "2")
    report = tmp_path / "report.html"
    run("report", str(job), "-o", str(report), "--previews", "3", "--tile", "96")

    html = report.read_text()
    assert "<script" not in html.lower()
    assert html.count("<svg") == 4, "four histograms"
    assert "broken.obj" in html, "the failures table lists the broken file"
    assert html.count("data:image/png;base64,") == 3

    found, n, dom = problems(report)
    assert n == 3, "three previews in the DOM"
    assert not found, "\n".join(found)
    assert "Failures (1)" in dom

    ARTEFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTEFACTS / "report.png"
    if shot.exists():
        shot.unlink()
    browse(report, "--screenshot=" + str(shot), "--window-size=1280,2000", "--hide-scrollbars")
    assert shot.exists() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", "screenshot written"
    assert browser
