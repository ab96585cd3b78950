#!/usr/bin/env python3
"""Peak memory of one VAE training step (forward + backward + AdamW) on CPU, per job and batch
size, for docs/VAE.md's memory notes. Each measurement runs in a fresh process on the largest
items of the job (the worst batch) and reports the process's peak RSS, the RSS before the step
(torch, the model, the data) and the cells in the batch.

    vae/bench/memory.py --data job64 job128 job256 --batch-sizes 1 4 [--config vae.toml]
"""

import argparse
import json
import subprocess
import sys

CHILD = r"""
import json, resource, sys
import torch
from sparc3d_vae.config import load_config
from sparc3d_vae.data import Samples, job_info, make_batch
from sparc3d_vae.loss import vae_loss
from sparc3d_vae.model import SparconvVAE

job, batch_size, config = sys.argv[1], int(sys.argv[2]), sys.argv[3] or None
cfg = load_config(config)
torch.set_num_threads(1)
info = job_info([job])
cfg.model.deformation = info.deformation
samples = Samples(info)
chosen = sorted((samples[i] for i in range(len(samples))), key=lambda s: -len(s.cells))[:batch_size]
model = SparconvVAE(cfg.model)
opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
x = make_batch(chosen, torch.device("cpu"))
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
dec, mean, logvar, structure = model(x)
loss, _ = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
loss.backward()
opt.step()
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"job": job, "resolution": info.resolutions, "batch_size": len(chosen),
                  "cells": int(len(x.coords)), "rss_before_step": before, "peak_rss": peak}))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", nargs="+", required=True)
    ap.add_argument("--batch-sizes", nargs="+", type=int, default=[1, 4])
    ap.add_argument("--config", default="")
    args = ap.parse_args()
    rows = []
    for job in args.data:
        for b in args.batch_sizes:
            out = subprocess.run([sys.executable, "-c", CHILD, job, str(b), args.config],
                                 check=True, capture_output=True, text=True).stdout
            row = json.loads(out.strip().splitlines()[-1])
            row["step_bytes_per_cell"] = (row["peak_rss"] - row["rss_before_step"]) / row["cells"]
            rows.append(row)
            print(json.dumps(row))
    print("| job | resolution | batch | cells | RSS before step | peak RSS | step bytes / cell |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['job']} | {r['resolution']} | {r['batch_size']} | {r['cells']} | "
              f"{r['rss_before_step'] / 2**20:.0f} MiB | {r['peak_rss'] / 2**20:.0f} MiB | "
              f"{r['step_bytes_per_cell']:.0f} |")


if __name__ == "__main__":
    main()
