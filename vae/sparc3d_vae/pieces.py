"""The pieces of a reconstruction against its Sparcubes mesh: the issue's bar (within ±20 %)
and whether the converter's own count holds one resolution step away (docs/VAE.md, "Pieces")."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Dict, Optional

from .runtime import run_sparc3d


def within_20pct(pieces: int, reference: int) -> bool:
    """The issue's bar for pieces: within ±20 % of the reference's count."""
    return abs(pieces - reference) <= 0.2 * reference


def nearby_pieces(binary: str, source: Path, resolution: int) -> Dict[int, int]:
    """Pieces of `sparc3d convert` of the source (default settings) at N − 1, N and N + 1.

    A piece count that changes between neighbouring resolutions is a property of where the
    grid falls, not of the shape: a speck one grid vertex wide, or two parts under a voxel
    apart, is kept or lost by a shift of a fraction of a voxel (docs/VAE.md, "Pieces")."""
    counts = {}
    with tempfile.TemporaryDirectory() as tmp:
        for n in (resolution - 1, resolution, resolution + 1):
            out = run_sparc3d(binary, "convert", source, "-o", Path(tmp) / "near.ply", "--resolution", n)
            counts[n] = int(out["output_components"])
    return counts


def pieces_stable(nearby: Dict[int, int], resolution: int, stored: int) -> Optional[bool]:
    """Whether the converter's own piece count holds at N ± 1 (both within ±20 % of N's); None
    where its count at N differs from the stored Sparcubes mesh's (the job was converted with
    other settings, so the nearby counts say nothing about it)."""
    if nearby[resolution] != stored:
        return None
    return all(within_20pct(nearby[n], stored) for n in (resolution - 1, resolution + 1))
