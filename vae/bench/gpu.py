#!/usr/bin/env python3
"""The VAE on a GPU at 256³ for a fixed few minutes: steps/s, cells (voxels)/s, peak GPU
memory, and the metrics of items it never saw (docs/VAE.md, "GPU").

    SPARC3D_BIN=sparc3d vae/bench/gpu.py --data JOB_OR_MESHES --work out/vae-gpu \\
        [--minutes 5] [--resolution 256] [--unseen 16] [--config vae.toml] [--procs 1]

--data is a converted job (a folder with job.json, at any resolution) or a folder of meshes,
converted here at --resolution with every core. The unseen items are held out of training
with `train --hold-out N --hold-out-seed 1` and evaluated with `evaluate --sample N --seed 1`
on the same job (the same seeded key as `sparc3d eval --sample`), so one job is enough.

The step count comes from the measured rate: a 30-step calibration run (which also warms up
CUDA), then minutes × 60 × the calibrated rate (the learning-rate schedule needs a step count).
--procs N trains with `torchrun --nproc_per_node N` (one GPU each). Needs torch with CUDA,
`sparc3d` (SPARC3D_BIN or PATH) and sparc3d-vae (installed, or the checkout on PYTHONPATH);
nothing is downloaded. Writes WORK/report.json (first after training, again with the
evaluation; `phases` holds the seconds of calibration and evaluation) and prints it.
"""

import argparse
import csv
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "ops" / "bench"))
from benchlib import binary as sparc3d_binary  # noqa: E402
from benchlib import fail  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: GPU settings on top of --config: a bigger global batch, a cell budget sized for tens of GB
#: (about 6 KB per cell measured on an H100, docs/VAE.md "GPU"), torch's own thread count.
GPU_TRAIN = {"batch_size": 8, "max_cells_per_batch": 3_000_000, "threads": 0,
             "checkpoint_every": 500, "log_every": 10}


def env():
    e = dict(os.environ)
    path = [str(ROOT / "python"), str(ROOT / "vae")]
    e["PYTHONPATH"] = os.pathsep.join(path + ([e["PYTHONPATH"]] if e.get("PYTHONPATH") else []))
    return e


def run(cmd, **kw):
    print("+", " ".join(map(str, cmd)), file=sys.stderr, flush=True)
    r = subprocess.run([str(c) for c in cmd], env=env(), text=True, capture_output=True, **kw)
    sys.stderr.write(r.stderr[-4000:])
    if r.returncode != 0:
        fail(f"{' '.join(map(str, cmd[:4]))} ... exited {r.returncode}")
    return r.stdout


def vae(procs, *args):
    if procs > 1:
        return [sys.executable, "-m", "torch.distributed.run", "--standalone",
                "--nproc_per_node", procs, "-m", "sparc3d_vae", *args]
    return [sys.executable, "-m", "sparc3d_vae", *args]


def write_config(base, out):
    """--config (or the defaults) with the GPU [train] keys set, as TOML."""
    sys.path[:0] = [str(ROOT / "python"), str(ROOT / "vae")]
    from sparc3d_vae.config import load_config

    cfg = load_config(base).to_dict()
    cfg["train"].update(GPU_TRAIN)
    cfg["model"].pop("deformation")  # set from the job

    def value(v):
        return json.dumps(v) if not isinstance(v, bool) else str(v).lower()

    text = "".join(f"[{sec}]\n" + "".join(f"{k} = {value(v)}\n" for k, v in keys.items()) + "\n"
                   for sec, keys in cfg.items())
    out.write_text(text)
    return cfg


def rate_from_log(run_dir):
    """Steps/s between the first and the last logged step (leaves out start-up)."""
    with open(run_dir / "loss.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) < 2:
        fail(f"{run_dir}/loss.csv: fewer than two logged steps")
    a, b = rows[0], rows[-1]
    steps = int(b["step"]) - int(a["step"])
    seconds = float(b["seconds"]) - float(a["seconds"])
    cells = sum(int(r["cells"]) for r in rows) / len(rows)  # cells of the logged steps
    return steps / seconds, cells


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, type=pathlib.Path)
    ap.add_argument("--work", required=True, type=pathlib.Path)
    ap.add_argument("--minutes", type=float, default=5.0)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--unseen", type=int, default=16)
    ap.add_argument("--config", type=pathlib.Path)
    ap.add_argument("--procs", type=int, default=1)
    ap.add_argument("--device", default="cuda", choices=["cuda", "cpu"],
                    help="cpu: a dry run of the script itself on a machine without a GPU")
    args = ap.parse_args()
    binary = sparc3d_binary()
    import torch

    if args.device == "cuda" and not torch.cuda.is_available():
        fail(f"torch {torch.__version__} sees no CUDA device: this benchmark needs a GPU")
    args.work.mkdir(parents=True, exist_ok=True)
    if (args.data / "job.json").exists():
        job = args.data
    else:
        job = args.work / f"job{args.resolution}"
        t0 = time.monotonic()
        run([binary, "run", args.data, "--job", job, "--resolution", args.resolution,
             "--workers", os.cpu_count() or 1])
        print(f"converted in {time.monotonic() - t0:.0f} s", file=sys.stderr)
    config = args.work / "gpu.toml"
    cfg = write_config(args.config, config)
    common = ["--data", job, "--config", config, "--device", args.device,
              "--hold-out", args.unseen, "--hold-out-seed", 1]

    phases = {}
    calib = args.work / "calibrate"
    shutil.rmtree(calib, ignore_errors=True)
    t0 = time.monotonic()
    run(vae(args.procs, "train", *common, "--out", calib, "--steps", 30))
    phases["calibrate_seconds"] = time.monotonic() - t0
    rate, _ = rate_from_log(calib)
    steps = max(30, int(args.minutes * 60 * rate))

    run_dir = args.work / "run"
    shutil.rmtree(run_dir, ignore_errors=True)
    t0 = time.monotonic()
    out = run(vae(args.procs, "train", *common, "--out", run_dir, "--steps", steps))
    wall = time.monotonic() - t0
    steps_per_s, cells_per_step = rate_from_log(run_dir)
    peak = re.search(r"peak GPU memory ([0-9.]+) GiB", out)
    gpu = torch.cuda.get_device_name(0) if args.device == "cuda" else None
    report = {"gpu": gpu, "processes": args.procs,
              "resolution": json.loads((job / "job.json").read_text())["config"]["params"]["resolution"],
              "config": cfg, "steps": steps, "train_wall_seconds": wall,
              "steps_per_second": steps_per_s, "cells_per_step": cells_per_step,
              "cells_per_second": steps_per_s * cells_per_step,
              "peak_gpu_gib_rank0": float(peak.group(1)) if peak else None,
              "train_stdout": out.strip().splitlines()[-2:], "phases": phases, "eval": None}
    # Written before the evaluation too, so that a run stopped during it (a lent machine's
    # time running out) still leaves the training figures.
    write_report(args.work, report)

    evals = {}
    t0 = time.monotonic()
    for name, sample in (("unseen", args.unseen),):
        ev = args.work / f"eval-{name}"
        shutil.rmtree(ev, ignore_errors=True)
        run(vae(1, "evaluate", "--ckpt", run_dir, "--data", job, "--sample", sample, "--seed", 1,
                "--out", ev, "--device", args.device))
        evals[name] = json.loads((ev / "summary.json").read_text())["aggregate"]
    phases["evaluate_seconds"] = time.monotonic() - t0
    report["eval"] = evals
    write_report(args.work, report)
    print(json.dumps({k: v for k, v in report.items() if k != "config"}, indent=2))


def write_report(work, report):
    """WORK/report.json, replaced whole."""
    tmp = work / "report.json.tmp"
    tmp.write_text(json.dumps(report, indent=2) + "\n")
    tmp.replace(work / "report.json")


if __name__ == "__main__":
    main()
