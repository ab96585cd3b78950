//! What the conversion measured of an item's source and output, stored in a row's quality
//! columns (the table `crate::columns::quality::QUALITY`; only in the shards of a job with
//! `quality = true`, the default of jobs made since they exist) so that a lab can choose what
//! to train on (`--where`), documented in docs/FORMAT.md, "Quality columns".

use serde::{Deserialize, Serialize};

/// What the conversion measured of an ok item's source and output.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct QualityFacts {
    /// Edges of the welded source used by exactly one triangle.
    pub boundary_edges: u64,
    /// Edges of the welded source used by more than two triangles.
    pub non_manifold_edges: u64,
    /// Source triangles of zero area (ignored by the conversion).
    pub degenerate_faces: u64,
    /// Source triangles dropped at load for repeating an earlier one's three vertices.
    pub duplicate_faces: u64,
    /// Extent of the source's bounding box along x, y, z, in its own units.
    pub extent: [f64; 3],
    /// Surface area of the source, in its units squared.
    pub surface_area: f64,
    /// Volume enclosed by the output mesh, in the source's units cubed (`None`: the mesh was
    /// not extracted).
    pub output_volume: Option<f64>,
    /// Connected components of the output mesh (`None`: the mesh was not extracted).
    pub output_components: Option<u64>,
    /// Regions sealed behind small openings and kept solid.
    pub sealed_pockets: u64,
}

impl QualityFacts {
    /// Longest extent over shortest: `inf` for a flat (or straight) source, whose shortest
    /// extent is 0; `None` when every extent is 0 (no ok row has such a source).
    pub fn aspect(&self) -> Option<f64> {
        let [lo, hi] = self
            .extent
            .iter()
            .fold([f64::INFINITY, 0.0f64], |[lo, hi], &e| {
                [lo.min(e), hi.max(e)]
            });
        match (lo, hi) {
            (_, h) if h <= 0.0 => None,
            (l, _) if l <= 0.0 => Some(f64::INFINITY),
            (l, h) => Some(h / l),
        }
    }
}
