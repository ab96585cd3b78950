"""`evaluate`: paper Table 2's metrics of reconstructions of a seeded sample of a job's items,
measured by `sparc3d eval` against each item's Sparcubes mesh (and its source when readable)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Dict, Optional, Sequence, Tuple

from .aggregate import aggregate
from .data import Sample, Samples
from .eval_report import markdown
from .loaded import Loaded
from .meshes import reconstruct_items, reported_pieces, safe_name
from .pieces import nearby_pieces, pieces_stable
from .runtime import UsageError, find_sparc3d, run_sparc3d
from .sampling import choose


def eval_samples(resolution: int) -> int:
    """Points `sparc3d eval` samples per mesh: its default 100,000 up to 128³; 1,000,000 from
    256³, where 100,000 points lie about 0.75 voxel apart and the CD and F1 measure mostly the
    sampling (docs/QUALITY.md, "Refinement against renderings"; docs/VAE.md, "256³ on CPU")."""
    return 100_000 if resolution <= 128 else 1_000_000


def evaluate(ckpt: Path, data: Sequence[str], sample: int, seed: int, out: Path, device: str,
             sparc3d: Optional[str], max_cells: Optional[int] = None,
             samples_per_mesh: Optional[int] = None) -> Dict[str, Any]:
    """Paper Table 2's metrics (CD, ANC, F1 via `sparc3d eval`) of reconstructions of a seeded
    sample of items against each item's Sparcubes mesh (and its source file when readable),
    and the share of watertight outputs before and after hole filling. Writes
    `out/summary.json`, `out/summary.md` and the meshes."""
    binary = find_sparc3d(sparc3d)
    loaded = Loaded(ckpt, device, max_cells)
    samples = loaded.load_samples(data)
    chosen = choose(samples.ids, sample, seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    items = [samples[samples.index_of(i)] for i in chosen]
    meshes = [out / f"{safe_name(s.id)}.vae.ply" for s in items]
    recon = reconstruct_items(loaded, items, binary, meshes, fill_holes=True)
    rows = [_evaluated(binary, samples, s, mesh, r, out, samples_per_mesh)
            for s, mesh, r in zip(items, meshes, recon)]
    summary = {"checkpoint": str(loaded.path), "data": list(data), "sample": len(rows),
               "seed": seed, "aggregate": aggregate(rows), "items": rows}
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (out / "summary.md").write_text(markdown(summary))
    return summary


def _evaluated(binary: str, samples: Samples, s: Sample, mesh: Path, r: Dict[str, Any],
               out: Path, samples_per_mesh: Optional[int]) -> Dict[str, Any]:
    """The summary row of one item: its reconstruction's sizes and, when it has a mesh, that
    mesh measured against the item's Sparcubes mesh (extracted into `out`) and its source."""
    res = int(s.meta["resolution"])
    row = {"id": s.id, "uri": s.meta["uri"], "resolution": res,
           "watertight_before_fill": r["watertight_before"], "watertight": r["watertight"],
           "holes": r.get("holes", 0), "faces": r.get("faces", 0),
           "latent_voxels": r["latent_voxels"], "latent_floats": r["latent_floats"],
           "true_cells": r["true_cells"], "decoded_cells": r["decoded_cells"]}
    if "error" in r:
        row["error"] = r["error"]
        print(f"{s.id}: {r['error']}", file=sys.stderr)
        return row
    i = samples.index_of(s.id)
    shard = samples.ds.paths[samples.ds.index[i][0]]
    ref = out / f"{safe_name(s.id)}.sparcubes.ply"
    ref_summary = run_sparc3d(binary, "extract", shard, "--id", s.id, "-o", ref)
    row["eval_samples"] = samples_per_mesh or eval_samples(res)
    counts = (reported_pieces(r, mesh), reported_pieces(ref_summary, ref))
    row.update(_measure(binary, mesh, ref, Path(s.meta["uri"]), res, row["eval_samples"], counts))
    print(f"{s.id}: CD {row['vs_sparcubes']['cd_voxels']:.3f} vox vs Sparcubes, "
          f"watertight {row['watertight_before_fill']} → {row['watertight']}", file=sys.stderr)
    return row


def _measure(binary: str, mesh: Path, ref: Path, src: Path, res: int, points: int,
             counts: Tuple[int, int]) -> Dict[str, Any]:
    """One reconstruction against its Sparcubes mesh, and both against the source when it is
    a readable file (the Sparcubes mesh is the floor the VAE cannot beat); the pieces of both
    (`counts`, as `sparc3d extract` reported them) and the converter's own at N ± 1."""
    ruler = ("--resolution", res, "--samples", points)
    row: Dict[str, Any] = {"vs_sparcubes": _metrics(run_sparc3d(binary, "eval", ref, mesh, *ruler)),
                           "components": counts[0], "sparcubes_components": counts[1]}
    if not src.is_file():
        return row
    try:
        row["vs_source"] = _metrics(run_sparc3d(binary, "eval", src, mesh, *ruler))
        row["sparcubes_vs_source"] = _metrics(run_sparc3d(binary, "eval", src, ref, *ruler))
    except UsageError as e:
        row["vs_source_error"] = str(e)
    try:
        nearby = nearby_pieces(binary, src, res)
        row["sparcubes_components_nearby"] = {str(n): c for n, c in nearby.items()}
        row["pieces_stable"] = pieces_stable(nearby, res, row["sparcubes_components"])
    except UsageError as e:
        row["nearby_error"] = str(e)
    return row


def _metrics(report: Dict[str, Any]) -> Dict[str, Any]:
    f1 = {f"f1@{f['threshold']}": f["f1"] for f in report.get("f1", [])}
    return {"cd_voxels": report["cd_voxels"], "cd": report["cd"], "anc": report["anc"], **f1}
