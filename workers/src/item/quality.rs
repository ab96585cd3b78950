//! The quality facts of an item (docs/FORMAT.md, "Quality columns"), measured in the conversion
//! pass from what it has at hand: the loaded source (its topology welded, as the input's
//! components always were; its bounds and area), what loading dropped, the conversion's counts,
//! and the extracted mesh (its volume and components). Each is one pass over the triangles.

use sparc3d_schema::QualityFacts;
use sparcubes::io::LoadStats;
use sparcubes::topology::{check, weld};
use sparcubes::{ConvertStats, Normalization, TriMesh};

/// What is measured of the source before it is converted (and dropped).
#[derive(Debug, Clone)]
pub struct SourceFacts {
    /// Connected components of the welded source (the row's `input_components`).
    pub components: u64,
    boundary_edges: u64,
    non_manifold_edges: u64,
    extent: [f64; 3],
    surface_area: f64,
}

/// Measures the loaded `source`: the topology of its welded copy, its bounding box and area.
pub fn source_facts(source: &TriMesh) -> SourceFacts {
    let topology = check(&weld(source));
    let extent = source
        .bounds()
        .map(|(lo, hi)| [0, 1, 2].map(|a| hi[a] - lo[a]))
        .unwrap_or_default();
    SourceFacts {
        components: topology.components,
        boundary_edges: topology.boundary_edges,
        non_manifold_edges: topology.non_manifold_edges,
        extent,
        surface_area: source.area(),
    }
}

/// What is measured of the extracted mesh: its volume in the source's units cubed and its
/// connected components.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputFacts {
    volume: f64,
    components: u64,
}

/// Measures the extracted `mesh` (in grid coordinates at `resolution`, placed by
/// `normalization`) of signed volume `grid_volume` (`TriMesh::signed_volume`, measured once
/// for these facts and the shape signature): a voxel's side is `1 / (resolution · scale)` source
/// units (`Normalization::grid_to_source`), so its volume is that cubed.
pub fn output_facts(
    mesh: &TriMesh,
    grid_volume: f64,
    normalization: &Normalization,
    resolution: u32,
) -> OutputFacts {
    let voxel = 1.0 / (f64::from(resolution) * normalization.scale);
    OutputFacts {
        volume: grid_volume * voxel.powi(3),
        components: sparcubes::topology::component_count(mesh),
    }
}

/// The row's quality facts.
pub fn facts(
    source: &SourceFacts,
    load: &LoadStats,
    stats: &ConvertStats,
    output: Option<OutputFacts>,
) -> QualityFacts {
    QualityFacts {
        boundary_edges: source.boundary_edges,
        non_manifold_edges: source.non_manifold_edges,
        degenerate_faces: stats.degenerate_faces,
        duplicate_faces: load.faces_duplicate,
        extent: source.extent,
        surface_area: source.surface_area,
        output_volume: output.map(|o| o.volume),
        output_components: output.map(|o| o.components),
        sealed_pockets: stats.sealed_pockets,
    }
}
