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


def frozen_records(job):
    """Every item of a job's frozen manifest as a dict, in order: the slices its index pages
    list (`manifest/`), or `manifest.jsonl` of a job made before slices."""
    import json
    job = pathlib.Path(job)
    meta = json.loads((job / "job.json").read_text())
    pages = meta.get("manifest_pages")
    if pages is None:
        return [json.loads(l) for l in (job / "manifest.jsonl").read_text().splitlines() if l.strip()]
    out = []
    for p, pin in enumerate(pages):
        page = job / "manifest" / f"index-{p:05d}.{pin['sha256'][:16]}.tsv"
        for line in page.read_text().splitlines():
            shard, _, _, sha = line.split("\t")
            part = job / "manifest" / f"part-{int(shard):05d}.{sha[:16]}.jsonl"
            out.extend(json.loads(l) for l in part.read_text().splitlines() if l.strip())
    return out


def rewrite_slice(job, shard, change):
    """Replaces shard `shard`'s slice of a job's frozen manifest with `change(text)` and pins
    the new bytes as `init` would have (its page, then job.json): a job frozen from other rows,
    not an edited one."""
    import hashlib
    import json
    job = pathlib.Path(job)
    meta = json.loads((job / "job.json").read_text())
    p = shard // 1024
    pin = meta["manifest_pages"][p]
    page = job / "manifest" / f"index-{p:05d}.{pin['sha256'][:16]}.tsv"
    lines = page.read_text().splitlines()
    s, first, count, sha = lines[shard % 1024].split("\t")
    text = change((job / "manifest" / f"part-{shard:05d}.{sha[:16]}.jsonl").read_text())
    new = hashlib.sha256(text.encode()).hexdigest()
    (job / "manifest" / f"part-{shard:05d}.{new[:16]}.jsonl").write_text(text)
    lines[shard % 1024] = "\t".join([s, first, count, new])
    page_text = "\n".join(lines) + "\n"
    page_sha = hashlib.sha256(page_text.encode()).hexdigest()
    (job / "manifest" / f"index-{p:05d}.{page_sha[:16]}.tsv").write_text(page_text)
    pin["sha256"] = page_sha
    root = hashlib.sha256("".join(q["sha256"] + "\n" for q in meta["manifest_pages"]).encode())
    meta["manifest_sha256"] = root.hexdigest()
    (job / "job.json").write_text(json.dumps(meta, indent=2))
