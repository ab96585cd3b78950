"""`summary.md` of an evaluation: its aggregate in a few lines and tables, then a row an item."""

from __future__ import annotations

from typing import Any, Dict, List

#: The comparisons of an evaluation, as the tables of summary.md title them.
TITLES = {"vs_sparcubes": "VAE output against the item's Sparcubes mesh",
          "vs_source": "VAE output against the source mesh",
          "sparcubes_vs_source": "Sparcubes mesh against the source mesh (the floor)"}


def markdown(summary: Dict[str, Any]) -> str:
    """The text of summary.md for an evaluation's `summary` (what summary.json holds)."""
    agg = summary["aggregate"]
    lines = [f"# VAE reconstruction: {summary['sample']} items", "",
             f"checkpoint `{summary['checkpoint']}`, data {', '.join(summary['data'])}, seed {summary['seed']}", ""]
    if agg:
        lines += _aggregate_lines(agg) + [""] + _metric_tables(agg)
    return "\n".join(lines + _item_table(summary["items"])) + "\n"


def _aggregate_lines(agg: Dict[str, Any]) -> List[str]:
    """The aggregate's watertight shares, latent size and pieces, a bullet each."""
    lines = [f"- watertight before hole filling: {100 * agg['watertight_before_fill']:.0f}%, "
             f"after: {100 * agg['watertight_after_fill']:.0f}%"
             + (f" ({agg['failed']} items failed, counted as not watertight)" if agg["failed"] else ""),
             f"- latent: {agg['latent_voxels_mean']:.1f} voxels, {agg['latent_floats_mean']:.0f} floats per shape (mean)"]
    if "components_median" not in agg:
        return lines
    lines.append(f"- pieces: median {agg['components_median']:g} (Sparcubes meshes: "
                 f"{agg['sparcubes_components_median']:g}); within ±20 % of the "
                 f"Sparcubes mesh's: {100 * agg['components_within_20pct']:.0f}% of items")
    if agg.get("components_within_20pct_stable") is not None:
        lines.append(f"- of the {agg['components_stable_items']} items whose piece count "
                     f"`sparc3d convert` keeps at N ± 1: "
                     f"{100 * agg['components_within_20pct_stable']:.0f}% within ±20 % "
                     f"(misses: {agg['components_stable_more']} with more pieces, "
                     f"{agg['components_stable_fewer']} with fewer)")
    if "sparcubes_nearby_within_20pct" in agg:
        near = agg["sparcubes_nearby_within_20pct"]
        lines.append(f"- the converter against itself: its pieces at N − 1 and N + 1 within "
                     f"±20 % of its own at N on {100 * near['n_minus_1']:.0f}% and "
                     f"{100 * near['n_plus_1']:.0f}% of items")
    return lines


def _metric_tables(agg: Dict[str, Any]) -> List[str]:
    """A table of each comparison's metrics (mean and median), each followed by a blank line."""
    lines: List[str] = []
    for against, title in TITLES.items():
        if against in agg:
            a = agg[against]
            keys = [k for k in a if k != "items"]
            lines += [f"{title} ({a['items']} items):", "",
                      "| metric | mean | median |", "|---|---|---|"]
            lines += [f"| {k} | {a[k]['mean']:.4g} | {a[k]['median']:.4g} |" for k in keys]
            lines.append("")
    return lines


def _item_table(items: List[Dict[str, Any]]) -> List[str]:
    """A row an item: its CD and ANC against its Sparcubes mesh, or why it failed."""
    lines = ["| id | CD vs Sparcubes (vox) | ANC | watertight before → after fill | latent voxels |",
             "|---|---|---|---|---|"]
    for r in items:
        if "error" in r:
            lines.append(f"| {r['id'][:16]} | failed: {r['error']} | | | {r['latent_voxels']} |")
            continue
        m = r["vs_sparcubes"]
        lines.append(f"| {r['id'][:16]} | {m['cd_voxels']:.3f} | {m['anc']:.1f} | "
                     f"{r['watertight_before_fill']} → {r['watertight']} | {r['latent_voxels']} |")
    return lines
