#!/usr/bin/env python3
"""The VAE on a corpus, as docs/VAE.md measures it: split the ok items of a converted job into
a training set and unseen items (by the seeded key of `sparc3d eval --sample`), convert each
part as its own job, train `sparc3d-vae` on the training job for a time budget, then evaluate
reconstructions of the unseen items and of as many training items against their Sparcubes
meshes and sources.

    vae/bench/dev_corpus.py --job dev64 --work out/vae-dev --train 128 --unseen 16 \\
        --minutes 30 --steps-per-second 0.75 [--config vae.toml] [--run NAME] [--steps S] \\
        [--init-from RUN] [--unseen-only]

`--unseen-job JOB` evaluates on a job of items from outside the corpus instead of a split:
all of the corpus's ok items (up to `--train`) are trained on, and every ok item of JOB is
unseen. `vae_heldout_manifest.tsv` beside this script names 24 such meshes (the dev corpus's
fetch script takes it as its MANIFEST argument; docs/VAE.md, "Measured: round three"):

    fetch.sh corpus vae/bench/vae_heldout_manifest.tsv
    sparc3d run corpus/vae_heldout --job held64 --resolution 64
    vae/bench/dev_corpus.py --job dev64 --work out --train 1000 --unseen-job held64 \
        --steps 2800 --run base

Several runs may share one WORK folder (`--run NAME`: WORK/NAME/ holds the run, its
evaluations and its report; the split jobs are converted once). `--steps` fixes the step count
instead of the time budget (for ablations that compare settings at equal steps).

The step count is minutes × 60 × --steps-per-second (train stops at a step count, and the
learning-rate schedule depends on it): measure the rate with a short `train` first.

Needs `sparc3d` (SPARC3D_BIN or PATH) and `sparc3d-vae` (`pip install ./python ./vae`).
Writes WORK/report.json with the split, training time, steps/s, peak memory and both
evaluation summaries.
"""

import argparse
import hashlib
import json
import pathlib
import resource
import struct
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "ops" / "bench"))
from benchlib import binary as sparc3d  # noqa: E402


def sample_key(seed, item_id):
    """The key of pipeline/src/rows/sample.rs: first 8 bytes, big-endian, of sha256(seed_le ‖ id)."""
    return int.from_bytes(hashlib.sha256(struct.pack("<Q", seed) + item_id.encode()).digest()[:8], "big")


def run(cmd, **kw):
    print("+", " ".join(map(str, cmd)), file=sys.stderr)
    subprocess.run([str(c) for c in cmd], check=True, **kw)


def vae(*args):
    return [sys.executable, "-m", "sparc3d_vae", *map(str, args)]


def ok_ids(job):
    import sparc3d_reader as reader

    ds = reader.SparseCubesDataset(job)
    return list(ds.ids)


def make_job(src_job, ids, work, name, resolution):
    """A job of the manifest records of `ids` (taken from the source job's frozen manifest)."""
    wanted = set(ids)
    lines = [l for l in (pathlib.Path(src_job) / "manifest.jsonl").read_text().splitlines()
             if json.loads(l)["id"] in wanted]
    manifest = work / f"{name}.jsonl"
    manifest.write_text("".join(json.dumps({k: v for k, v in json.loads(l).items()
                                            if k not in ("index", "shard")}) + "\n" for l in lines))
    job = work / name
    if not (job / "job.json").exists():
        run([sparc3d(), "init", job, "--manifest", manifest, "--resolution", resolution])
    run([sparc3d(), "run", job, "--workers", 2])
    return job


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--job", required=True, help="a converted job holding the corpus")
    ap.add_argument("--work", required=True, type=pathlib.Path)
    ap.add_argument("--train", type=int, default=128)
    ap.add_argument("--unseen", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--minutes", type=float, default=30.0, help="training time budget")
    ap.add_argument("--steps-per-second", type=float, default=0.5,
                    help="measured rate, to turn the budget into a step count")
    ap.add_argument("--config", type=pathlib.Path)
    ap.add_argument("--init-from", type=pathlib.Path,
                    help="start from another run's weights (e.g. a 64³ run for a 128³ one)")
    ap.add_argument("--run", default="run", help="name of the run folder under WORK")
    ap.add_argument("--steps", type=int, help="step count (instead of minutes × rate)")
    ap.add_argument("--unseen-only", action="store_true", help="evaluate the unseen items only")
    ap.add_argument("--unseen-job", type=pathlib.Path,
                    help="a converted job of items from outside the corpus: evaluate on all of its "
                         "items, and train on the corpus's first --train items (no split)")
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    config = json.loads((pathlib.Path(args.job) / "job.json").read_text())["config"]
    resolution = config["params"]["resolution"]

    ids = sorted(ok_ids(args.job), key=lambda i: (sample_key(args.seed, i), i))
    if args.unseen_job:
        unseen, training = ok_ids(args.unseen_job), ids[:args.train]
        unseen_job = args.unseen_job
    else:
        unseen, training = ids[:args.unseen], ids[args.unseen:args.unseen + args.train]
        unseen_job = make_job(args.job, unseen, args.work, "unseen", resolution)
    # Training on every ok item of the corpus needs no copy of its job.
    whole = args.unseen_job and len(training) == len(ids)
    train_job = args.job if whole else make_job(args.job, training, args.work, "train", resolution)

    steps = args.steps or int(args.minutes * 60 * args.steps_per_second)
    home = args.work if args.run == "run" else args.work / args.run
    home.mkdir(parents=True, exist_ok=True)
    run_dir = args.work / "run" if args.run == "run" else home / "run"
    cmd = vae("train", "--data", train_job, "--out", run_dir, "--steps", steps, "--device", "cpu")
    if args.config:
        cmd += ["--config", args.config]
    if args.init_from:
        cmd += ["--init-from", args.init_from]
    began = time.monotonic()
    run(cmd)
    seconds = time.monotonic() - began
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    report = {"split": {"train": len(training), "unseen": len(unseen), "seed": args.seed},
              "resolution": resolution, "steps": steps, "train_seconds": seconds,
              "steps_per_second": steps / seconds, "train_peak_rss_bytes": peak,
              "init_from": str(args.init_from) if args.init_from else None}
    evals = (("unseen", unseen_job, len(unseen)), ("train", train_job, len(unseen)))
    for name, job, n in evals[:1] if args.unseen_only else evals:
        out = home / f"eval-{name}"
        run(vae("evaluate", "--ckpt", run_dir, "--data", job, "--sample", n,
                "--out", out, "--device", "cpu"), stdout=subprocess.DEVNULL)
        report[f"eval_{name}"] = json.loads((out / "summary.json").read_text())["aggregate"]
    (home / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
