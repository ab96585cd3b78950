"""The `aggregate` of an evaluation's summary: shares, means and medians over its items."""

from __future__ import annotations

import statistics
from typing import Any, Callable, Dict, List, Optional

from .pieces import within_20pct


def _median(xs: List[float]) -> Optional[float]:
    return statistics.median(xs) if xs else None


def _mean(xs: List[float]) -> Optional[float]:
    return statistics.fmean(xs) if xs else None


def aggregate(rows: List[Dict[str, Any]]) -> Dict[str, Any]:
    """Over the items of an evaluation (`rows`, as `evaluate` writes them): the share that
    failed or is watertight, the latent's mean size, the pieces' figures, and the mean and
    median of every metric of each comparison; {} for no items."""
    agg: Dict[str, Any] = {}
    if not rows:
        return agg
    n = len(rows)
    agg["failed"] = sum("error" in r for r in rows)
    agg["watertight_before_fill"] = sum(r["watertight_before_fill"] for r in rows) / n
    agg["watertight_after_fill"] = sum(r["watertight"] for r in rows) / n
    agg["latent_voxels_mean"] = _mean([r["latent_voxels"] for r in rows])
    agg["latent_floats_mean"] = _mean([r["latent_floats"] for r in rows])
    pieces = [r for r in rows if "components" in r]
    if pieces:
        agg.update(_pieces_aggregate(pieces))
    for against in ("vs_sparcubes", "vs_source", "sparcubes_vs_source"):
        have = [r[against] for r in rows if against in r]
        if not have:
            continue
        agg[against] = {k: {"mean": _mean([h[k] for h in have]), "median": _median([h[k] for h in have])}
                        for k in have[0]}
        agg[against]["items"] = len(have)
    return agg


def _miss(row: Dict[str, Any]) -> int:
    """+1 where an item has more pieces than the bar allows, −1 where fewer, 0 within it."""
    pieces, reference = row["components"], row["sparcubes_components"]
    if within_20pct(pieces, reference):
        return 0
    return 1 if pieces > reference else -1


def _pieces_aggregate(pieces: List[Dict[str, Any]]) -> Dict[str, Any]:
    """The issue's bar (the output's pieces within ±20 % of the Sparcubes mesh's) on every
    item and on the items whose count the converter itself keeps at N ± 1, and the bar applied
    to the converter against itself one resolution step away: what the count is worth as a
    target (docs/VAE.md, "Pieces")."""
    def share(items: List[Dict[str, Any]], key: Callable[[Dict[str, Any]], int]) -> Optional[float]:
        hits = sum(within_20pct(key(r), r["sparcubes_components"]) for r in items)
        return hits / len(items) if items else None

    stable = [r for r in pieces if r.get("pieces_stable")]
    agg: Dict[str, Any] = {
        "components_median": _median([r["components"] for r in pieces]),
        "sparcubes_components_median": _median([r["sparcubes_components"] for r in pieces]),
        "components_within_20pct": share(pieces, lambda r: r["components"]),
        "components_stable_items": len(stable),
        "components_within_20pct_stable": share(stable, lambda r: r["components"]),
        # Which way the stable items that miss the bar miss it: more pieces (a speck the
        # decoder adds) or fewer (a piece it loses); docs/VAE.md, "Pieces".
        "components_stable_more": sum(_miss(r) > 0 for r in stable),
        "components_stable_fewer": sum(_miss(r) < 0 for r in stable),
    }
    near = [r for r in pieces if r.get("pieces_stable") is not None]
    if near:
        agg["sparcubes_nearby_within_20pct"] = {
            side: share(near, lambda r, step=step: r["sparcubes_components_nearby"][str(r["resolution"] + step)])
            for side, step in (("n_minus_1", -1), ("n_plus_1", 1))}
    return agg
