"""`sparc3d-vae` (or `python -m sparc3d_vae`): train / encode / decode / reconstruct / evaluate.

Bad input (a job of another schema version, an item with no active cells, a checkpoint of
another config, `--device cuda` without a GPU, a missing `sparc3d` binary) ends with one
`error: ...` line naming the thing and exit status 2, not a stack trace.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import List, Optional

from . import __version__


def _device(p: argparse.ArgumentParser) -> None:
    p.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"],
                   help="where to run: auto (CUDA when available, else CPU; the default), cpu, cuda")


def _ckpt(p: argparse.ArgumentParser, data: bool = True) -> None:
    p.add_argument("--ckpt", type=Path, required=True, help="checkpoint file or run folder")
    if data:
        p.add_argument("--data", nargs="+", required=True, metavar="JOB",
                       help="job folders (or shard files)")


def _budget(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-cells", type=int, metavar="N",
                   help="cells per forward pass (default: the checkpoint's "
                        "train.max_cells_per_batch); no gradients are kept here, so a larger "
                        "budget than training's usually fits: raise it to run a model on a "
                        "finer grid than it was trained on")


def _sparc3d(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sparc3d", metavar="PATH",
                   help="the sparc3d binary (default: $SPARC3D_BIN, else sparc3d on PATH)")


def _mesh_run(p: argparse.ArgumentParser) -> None:
    """Where a command that ends in meshes runs: the device, the cell budget, the binary."""
    _device(p)
    _budget(p)
    _sparc3d(p)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="sparc3d-vae",
        description="Sparconv-VAE (Sparc3D §3.5) on sparc3d shards: train, encode to sparse "
                    "latents, decode back to watertight meshes. See docs/VAE.md.")
    ap.add_argument("--version", action="version", version=f"sparc3d-vae {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_train_parser, _encode_parser, _decode_parser, _reconstruct_parser,
                _evaluate_parser):
        add(sub)
    return ap


def _train_parser(sub) -> None:
    p = sub.add_parser("train", help="train a VAE on the items of one or more jobs",
                       description="Train (or with --resume continue) a VAE on the ok items of "
                       "jobs, with the settings measured for the jobs' resolution "
                       "(sparc3d_vae/configs/N.toml; a resolution without its own takes the "
                       "largest measured one below it, jobs of several resolutions the finest's; "
                       "a line on stderr says which) and --config's keys on top. "
                       "Writes RUN/config.json, RUN/loss.csv, RUN/tensorboard/ (when "
                       "TensorBoard is installed) and RUN/checkpoint.pt every "
                       "train.checkpoint_every steps. bf16 autocast on CUDA; on CPU a run with "
                       "the same seed gives the same weights, also across --resume. Several "
                       "processes: `torchrun --nproc_per_node N -m sparc3d_vae train ...` "
                       "(train.batch_size is the global batch, a multiple of N).")
    p.add_argument("--data", nargs="+", required=True, metavar="JOB",
                   help="job folders (or shard files) to train on")
    p.add_argument("--config", type=Path, metavar="vae.toml",
                   help="settings on top of the job's measured ones, key by key (vae/vae.toml "
                   "documents every key); with --resume, on top of the run's")
    p.add_argument("--out", type=Path, required=True, metavar="RUN", help="run folder")
    p.add_argument("--steps", type=int, help="optimizer steps in total (default: train.steps)")
    p.add_argument("--seed", type=int, help="seed (default: train.seed)")
    p.add_argument("--resume", action="store_true",
                   help="continue the run in RUN from its last checkpoint")
    p.add_argument("--init-from", type=Path, metavar="CKPT",
                   help="start a new run from the weights (EMA when kept) of another run's "
                   "checkpoint or run folder, trained at any resolution: its [model], the job's "
                   "measured training settings, then --config's keys (a [model] key of it must "
                   "match the source's)")
    p.add_argument("--hold-out", type=int, metavar="N",
                   help="leave out the N items `evaluate --sample N --seed S` picks (train.hold_out)")
    p.add_argument("--hold-out-seed", type=int, metavar="S", help="their seed (train.hold_out_seed)")
    _device(p)


def _encode_parser(sub) -> None:
    p = sub.add_parser("encode", help="write the latents of a job's items as Parquet shards, "
                       "or into a TRELLIS.2 export",
                       description="Encode every ok item of the jobs (the posterior mean and "
                       "log-variance on the latent grid) into LATENTS/part-NNNNN.parquet, "
                       "readable with sparc3d_reader.iter_tensor_rows. With --format trellis2, "
                       "EXPORT is a `sparc3d export --format trellis2` folder of the same job: "
                       "each of its items' latent (the mean) goes to "
                       "EXPORT/<key>s/<name>/<sha256>.npz (coords, feats) with that folder's "
                       "metadata.csv (<key>_encoded, <key>_tokens), normalization.json (per-"
                       "channel mean and std over the export, for the config's "
                       "dataset.args.normalization) and data_dir.json's <key> entry: what "
                       "TRELLIS.2's SLat dataset reads (docs/VAE.md).")
    _ckpt(p)
    p.add_argument("--out", type=Path, required=True, metavar="LATENTS|EXPORT")
    p.add_argument("--format", choices=["parquet", "trellis2"], default="parquet",
                   help="parquet: latent shards in LATENTS (the default); trellis2: into the "
                   "TRELLIS.2 export EXPORT, keyed by its sha256s")
    p.add_argument("--latent-key", default="shape_latent", metavar="KEY",
                   help="with --format trellis2: SLat's latent_key, the data_dir.json entry and "
                   "the metadata columns' prefix (shape_latent, what SLatShape reads)")
    p.add_argument("--latent-name", metavar="NAME",
                   help="with --format trellis2: the folder under EXPORT/<KEY>s/ (default "
                   "sparc3d_vae_<checkpoint digest>_<G>)")
    _device(p)
    _budget(p)


def _decode_parser(sub) -> None:
    p = sub.add_parser("decode", help="decode latents to meshes",
                       description="Decode latents (their mean) to pruned sparse cubes, extract "
                       "each mesh with `sparc3d extract` and close its holes (paper §3.4): "
                       "MESHES/<id>.ply. LATENTS: the Parquet shards of `encode`, or npz "
                       "latents in TRELLIS.2's layout (one .npz, or a folder of them such as "
                       "`encode --format trellis2` writes; --id takes an id or a sha256).")
    _ckpt(p, data=False)
    p.add_argument("--latents", type=Path, required=True, metavar="LATENTS")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--id", action="append", metavar="X", help="item id (repeatable)")
    which.add_argument("--all", action="store_true", help="every item of LATENTS")
    p.add_argument("--out", type=Path, required=True, metavar="MESHES")
    p.add_argument("--no-fill-holes", action="store_true", help="keep the extracted mesh as is")
    p.add_argument("--normalized-by", type=Path, metavar="normalization.json",
                   help="npz latents whose feats are normalised, (feats - mean) / std, such as "
                   "a sample of TRELLIS.2's flow: un-normalised with this file's mean and std "
                   "(the normalization.json beside the export's latents) before decoding")
    p.add_argument("--resolution", type=int, metavar="N",
                   help="the job grid of npz latents that carry none (a flow's sample: "
                   "`resolution` in the latent folder's .sparc3d-latents.json); their mesh is "
                   "written in that grid's [-0.5, 0.5] frame")
    _mesh_run(p)


def _reconstruct_parser(sub) -> None:
    p = sub.add_parser("reconstruct", help="one item of a job through the VAE to a mesh",
                       description="Encode an item (posterior mean), decode it, extract the "
                       "mesh with `sparc3d extract` and fill its holes.")
    _ckpt(p)
    p.add_argument("--id", required=True, metavar="X", help="item id")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="mesh.ply")
    p.add_argument("--no-fill-holes", action="store_true", help="keep the extracted mesh as is")
    p.add_argument("--tensors", type=Path, metavar="cubes.parquet",
                   help="also keep the decoded sparse cubes as a tensor file")
    _mesh_run(p)


def _evaluate_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="CD / ANC / F1 and watertightness of reconstructions",
                       description="Reconstruct a seeded sample of items (the sample of "
                       "`sparc3d eval JOB --sample N --sample-seed S`) and measure each with "
                       "`sparc3d eval` against the item's Sparcubes mesh and its source file; "
                       "writes OUT/summary.json, OUT/summary.md and the meshes.")
    _ckpt(p)
    p.add_argument("--sample", type=int, default=10, metavar="N", help="items to evaluate (10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sample (0)")
    p.add_argument("--out", type=Path, default=Path("vae-eval"), metavar="DIR",
                   help="where the summary and meshes go (./vae-eval)")
    p.add_argument("--eval-samples", type=int, metavar="N",
                   help="points `sparc3d eval` samples per mesh (default: 100000 up to 128³, "
                        "1000000 above, where fewer lie too far apart to measure a voxel's "
                        "fraction)")
    _mesh_run(p)


def main(argv: Optional[List[str]] = None) -> int:
    args = parser().parse_args(argv)
    # OpenMP threads that spin while waiting slow torch down many times over on a machine whose
    # cores are busy with other work (measured in docs/VAE.md); waiting passively costs little
    # on an idle one. Must be set before torch is imported; an explicit setting wins.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    # Imported here so that `--help` answers without loading torch.
    from .config import ConfigError
    from .data import DataError
    from .model import TooManyVoxels
    from .runtime import UsageError

    try:
        return _run(args)
    except (ConfigError, DataError, UsageError, TooManyVoxels) as e:
        # Under torchrun every process meets the same bad input: rank 0 says it once.
        if os.environ.get("RANK", "0") in ("", "0"):
            print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def _run(args: argparse.Namespace) -> int:
    from . import infer, train
    from .runtime import UsageError

    if args.command == "train":
        summary = train.train(args.data, args.out, args.config, args.steps, args.device,
                              args.resume, args.seed, args.hold_out, args.hold_out_seed,
                              args.init_from)
        if os.environ.get("RANK", "0") not in ("", "0"):
            return 0
        t = summary["terms"]
        print(f"trained {summary['steps']} steps (from {summary['resumed_from']}) on "
              f"{summary['items']} items in {summary['seconds']:.0f} s "
              f"({summary['steps_per_second']:.2f} steps/s); last loss "
              f"{t.get('loss', float('nan')):.4f}; checkpoint {args.out / 'checkpoint.pt'}")
        peak = summary["peak_gpu_bytes"]
        print(f"{summary['cells_per_second']:.0f} cells/s on {summary['world_size']} process(es)"
              + (f"; peak GPU memory {peak / 2**30:.2f} GiB (rank 0)" if peak is not None else ""))
    elif args.command == "encode":
        if args.format == "trellis2":
            return _encode_trellis2(args)
        if args.latent_name is not None or args.latent_key != "shape_latent":
            raise UsageError("--latent-key and --latent-name are for --format trellis2")
        s = infer.encode(args.ckpt, args.data, args.out, args.device, args.max_cells)
        print(f"{s['items']} items encoded into {s['shards']} shard(s) in {args.out}; "
              f"{s['latent_voxels_mean']:.1f} latent voxels × {s['latent_channels']} channels "
              "per item on average")
    elif args.command == "decode":
        rows = infer.decode(args.ckpt, args.latents, None if args.all else args.id, args.out,
                            args.device, not args.no_fill_holes, args.sparc3d, args.max_cells,
                            args.normalized_by, args.resolution)
        for r in rows:
            if "error" in r:
                print(f"error: {r['error']}", file=sys.stderr)
            else:
                print(f"{r['id']}: {r['faces']} faces, watertight {r['watertight']} → {r['output']}")
        if any("error" in r for r in rows):
            return 1
    elif args.command == "reconstruct":
        r = infer.reconstruct(args.ckpt, args.data, args.id, args.output, args.device,
                              not args.no_fill_holes, args.sparc3d, args.tensors, args.max_cells)
        print(json.dumps(r))
    elif args.command == "evaluate":
        infer.evaluate(args.ckpt, args.data, args.sample, args.seed, args.out, args.device,
                       args.sparc3d, args.max_cells, args.eval_samples)
        print((args.out / "summary.md").read_text())
    return 0


def _encode_trellis2(args: argparse.Namespace) -> int:
    """`encode --format trellis2`: its summary, each failed item on stderr (exit 1 if any)."""
    from . import trellis2_latents

    s = trellis2_latents.encode(args.ckpt, args.data, args.out, args.device, args.max_cells,
                                args.latent_key, args.latent_name)
    for f in s["failed"]:
        print(f"error: {f['id']} (sha256 {f['sha256']}): {f['error']}", file=sys.stderr)
    print(f"{s['items']} items of {args.out} encoded into {s['folder']} "
          f"({s['tokens_mean']:.1f} tokens × {s['latent_channels']} channels on average, latent "
          f"grid {s['latent_grid']}); data_dir.json lists it as {s['latent_key']!r}; "
          f"normalization.json beside it"
          + (f"; {s['not_exported']} ok items of the job(s) are not in the export"
             if s["not_exported"] else ""))
    return 1 if s["failed"] else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
