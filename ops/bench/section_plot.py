#!/usr/bin/env python3
"""Cross-sections of a source mesh and of two outputs through one plane, side by side, as a
PNG (docs/QUALITY.md): what a conversion made of a part's inside, which views from outside do
not show (a solid and a hollow shell look alike from outside).

    python3 ops/bench/section_plot.py SOURCE BEFORE.ply AFTER.ply --axis 0 --at 1.33 -o out.png

Needs trimesh and matplotlib (`pip install trimesh matplotlib`); the meshes must be in one frame
(`sparc3d convert` writes outputs in the source's frame).
"""

import argparse

import matplotlib
import numpy as np
import trimesh

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source")
    p.add_argument("before")
    p.add_argument("after")
    p.add_argument("--axis", type=int, default=0, help="the plane's normal axis (0, 1, 2)")
    p.add_argument("--at", type=float, required=True, help="the plane's coordinate on that axis")
    p.add_argument("--titles", default="source,before,after")
    p.add_argument("-o", "--out", required=True)
    args = p.parse_args()
    normal = np.eye(3)[args.axis]
    keep = [i for i in range(3) if i != args.axis]
    titles = args.titles.split(",")
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.2))
    for ax, path, title in zip(axes, [args.source, args.before, args.after], titles):
        mesh = trimesh.load(path, force="mesh", process=False)
        section = mesh.section(plane_origin=normal * args.at, plane_normal=normal)
        if section is not None:
            for entity in section.entities:
                line = section.vertices[entity.points]
                ax.plot(line[:, keep[0]], line[:, keep[1]], lw=0.7, color="k")
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=10)
        ax.tick_params(labelsize=7)
    plt.tight_layout()
    plt.savefig(args.out, dpi=60)


if __name__ == "__main__":
    main()
