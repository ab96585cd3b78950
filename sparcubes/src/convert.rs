//! The conversion driver: the stages of docs/ALGORITHM.md, top to bottom, each a free function
//! of `stages/` over plain data (§1–10, and §12 when asked); the extraction (§11) is
//! [`crate::extract()`].

use crate::error::Result;
use crate::grid::cubes::SparseCubes;
use crate::grid::normalization::Normalization;
use crate::grid::{dilate, Dilation};
use crate::mesh::TriMesh;
use crate::params::Params;
use crate::queries::winding::LazyWindingTree;
use crate::stages::assemble::{assemble, free_vertices, Core};
use crate::stages::band::{compute_band, triangle_planes, Band, CORE_REACH};
use crate::stages::deform::compute_field;
use crate::stages::extract::extract;
use crate::stages::flood::{flood_outside, Flood};
use crate::stages::frame::{first_span, refit, snap, REFITS};
use crate::stages::inside::classify::classify_regions;
use crate::stages::inside::nesting::Nesting;
use crate::stages::inside::regions::{mark_air, Regions};
use crate::stages::inside::sealed::decide_sealed;
use crate::stages::inside::winding_piece;
use crate::stages::normalize::normalize;
use crate::stages::refine::{refine, RefineStats};
use crate::stages::ring::{ring, RingInputs};
use crate::stages::seal::{seal_openings, Sealing};
use crate::stages::sign::{compute_signs, sealed_to_outside, vertex_sides, CoreSigns};
use crate::stages::voxelize::{voxelize, Voxelization};
use std::time::Instant;

/// Wall-clock seconds and counts of one conversion.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConvertStats {
    /// Seconds per stage, in order: (stage name, seconds).
    pub stage_seconds: Vec<(&'static str, f64)>,
    /// Input triangles.
    pub input_faces: u64,
    /// Input vertices.
    pub input_vertices: u64,
    /// Input triangles with zero area, which bound nothing and are ignored.
    pub degenerate_faces: u64,
    /// Cells touched by the surface.
    pub wall_cells: u64,
    /// Band vertices whose distance was computed (corners of the wall cells, plus the corners
    /// of the ring cells a thin shell reaches; a vertex in both counts twice).
    pub band_vertices: u64,
    /// Surface-free cells next to the walls that got a band of their own (`crate::stages::ring`).
    pub ring_cells: u64,
    /// Active vertices stored.
    pub active_vertices: u64,
    /// Active cells stored.
    pub active_cells: u64,
    /// Stored vertices that belong to a thin shell around an open part.
    pub shell_vertices: u64,
    /// Enclosed regions: connected sets of surface-free cells the outside flood cannot reach
    /// (`crate::stages::inside`).
    pub enclosed_regions: u64,
    /// Enclosed regions the winding number found to be air (treated as outside).
    pub air_regions: u64,
    /// Enclosed regions whose winding number was ambiguous (kept solid).
    pub ambiguous_regions: u64,
    /// Closed parts thinner than about two cells, found inside by the winding number (groups
    /// of sealed vertices joined with their 26 neighbours, `crate::stages::inside::sealed::decide_sealed`).
    pub thin_parts: u64,
    /// Sealed parts left to the thin shell: found inside by the winding number but too thin
    /// somewhere for the grid (under a cell), or nowhere 0.3 voxel deep (these are shelled
    /// without asking the winding number, so the count includes any such pocket).
    pub shelled_thin_parts: u64,
    /// Regions sealed behind small openings and kept solid: nearly closed parts whose
    /// openings the walls grown at the sealing scale close (`crate::stages::seal`), read as solid by
    /// the winding number on the coarse grid and again as enclosed regions (§6).
    pub sealed_pockets: u64,
    /// Groups of sealed vertices inside two closed surfaces or more: closed parts overlapping
    /// by less than the grid resolves, left outside so both keep their surfaces
    /// (`crate::stages::inside::sealed::OVERLAP_FROM`).
    pub overlap_groups: u64,
    /// What the rendering-based refinement did (`None`: it was off), [`crate::stages::refine`].
    pub refine: Option<RefineStats>,
}

/// A conversion's result.
#[derive(Debug, Clone)]
pub struct Conversion {
    /// The sparse cubes.
    pub cubes: SparseCubes,
    /// Timings and counts.
    pub stats: ConvertStats,
}

/// The conversion's counts so far, and the clock of its stages.
struct Stages {
    stats: ConvertStats,
    last: Instant,
}

impl Stages {
    /// The clock started, with the input's counts.
    fn start(mesh: &TriMesh) -> Self {
        Self {
            stats: ConvertStats {
                input_faces: mesh.triangles.len() as u64,
                input_vertices: mesh.positions.len() as u64,
                ..Default::default()
            },
            last: Instant::now(),
        }
    }

    /// Books the time since the last call to stage `name` (added to it if it ran before).
    fn done(&mut self, name: &'static str) {
        let now = Instant::now();
        let seconds = (now - self.last).as_secs_f64();
        match self
            .stats
            .stage_seconds
            .iter_mut()
            .find(|(n, _)| *n == name)
        {
            Some(entry) => entry.1 += seconds,
            None => self.stats.stage_seconds.push((name, seconds)),
        }
        self.last = now;
    }
}

/// Converts a sanitised mesh into sparse cubes (docs/ALGORITHM.md §1–10 and, when
/// `params.refine` asks, §12; extraction, §11, is [`crate::extract()`]).
/// With `params.output_span` the output's box is framed instead of the source's (§13,
/// [`crate::stages::frame`]): the conversion runs two or three times.
pub fn convert(mesh: &TriMesh, params: &Params) -> Result<Conversion> {
    params.validate()?;
    match params.output_span {
        Some(span) => convert_framed(mesh, params, span),
        None => convert_at(mesh, params, None),
    }
}

/// The conversion of `mesh` with its output's box framed to `span` of the grid ([`crate::stages::frame`]'s docs).
fn convert_framed(mesh: &TriMesh, params: &Params, span: f64) -> Result<Conversion> {
    let base = Params {
        output_span: None,
        object_span: None,
        ..*params
    };
    let first = Params {
        object_span: Some(first_span(span, params.resolution, params.margin_cells)),
        ..base
    };
    let mut conversion = convert_at(mesh, &first, None)?;
    let mut earlier = total_seconds(&conversion);
    let Some(source) = mesh.bounds() else {
        return Ok(conversion);
    };
    for _ in 0..REFITS {
        let Some(output) = extract(&conversion.cubes).bounds() else {
            return Ok(conversion);
        };
        let fit = refit(&conversion.cubes, output, span, source, base.margin_cells);
        let mut next = convert_at(mesh, &base, Some(fit))?;
        let snapped = snap(&mut next.cubes, span).is_ok();
        next.stats.stage_seconds.push(("frame", earlier));
        earlier += total_seconds(&next);
        conversion = next;
        if snapped {
            break;
        }
    }
    Ok(conversion)
}

/// Seconds of every stage of `c`.
fn total_seconds(c: &Conversion) -> f64 {
    c.stats.stage_seconds.iter().map(|(_, s)| s).sum()
}

/// One conversion, with the normalization `fit` (else the source's box fitted to
/// `params.span()`).
pub(crate) fn convert_at(
    mesh: &TriMesh,
    params: &Params,
    fit: Option<Normalization>,
) -> Result<Conversion> {
    let n = params.resolution;
    let mut st = Stages::start(mesh);
    // §1: the mesh in grid coordinates.
    let (grid, norm, degenerate) = normalize(mesh, params, fit)?;
    st.stats.degenerate_faces = degenerate;
    st.done("normalize");
    // §2: wall cells and crossed grid edges.
    let mut vox = voxelize(&grid, n);
    st.stats.wall_cells = vox.walls.len();
    st.done("voxelize");
    // §3: the outside cells.
    let mut flood = flood_outside(&vox.walls);
    st.done("flood");
    // The inside test's winding number (§6), built on first use; the sealing (§4) asks it
    // about the pockets it finds.
    let tree = params
        .inside_test
        .then(|| LazyWindingTree::new(&grid, winding_piece(n)));
    // §4: openings small for their part.
    let sealing = seal(&mut vox, &mut flood, tree.as_ref(), params, &mut st);
    // §5: distances and closest points at the corners of the wall cells.
    let planes = triangle_planes(&grid);
    let core_verts = dilate(&vox.walls, n, Dilation::Corners);
    let band = compute_band(&grid, &planes, core_verts, CORE_REACH);
    st.done("band");
    // §6, first step: the enclosed regions.
    let regions = enclosed_regions(tree.as_ref(), &vox, &mut flood, &band, &sealing, &mut st);
    // §7, with §6's sealed vertices and nesting between its halves.
    let core_signs = sign(tree, &band, &vox, &flood, &regions, n, &mut st);
    // §8: φ and the displacement of every core vertex.
    let field = compute_field(&band, &core_signs.signs, params);
    st.done("deform");
    // §9: the ring's cells and vertices.
    let inputs = RingInputs {
        grid: &grid,
        planes: &planes,
        core: &band,
        signs: &core_signs,
        sdf: &field.sdf,
        walls: &vox.walls,
        flood: &flood,
    };
    let ring = ring(&inputs, sealing.caps, params);
    st.stats.ring_cells = ring.cells.len();
    st.stats.band_vertices = (band.verts.len + ring.band.verts.len) as u64;
    st.done("ring");
    // §10: the stored cubes.
    let core = Core {
        band: &band,
        signs: &core_signs.signs,
        field: &field,
    };
    let assembly = assemble(core, &ring, &vox.walls, norm, params)?;
    st.stats.shell_vertices = assembly.shell_vertices;
    st.stats.active_vertices = assembly.cubes.coords.len() as u64;
    st.stats.active_cells = assembly.cubes.cells.len() as u64;
    st.done("assemble");
    let mut cubes = assembly.cubes;
    // §12 (optional): the displacements refined against renderings of the source.
    if let Some(settings) = &params.refine {
        let free = free_vertices(&assembly.ids, &core_signs.signs, &ring.signs);
        let stats = refine(&mut cubes, &grid, &free, settings, params.deform_max);
        st.stats.refine = Some(stats);
        st.done("refine");
    }
    Ok(Conversion {
        cubes,
        stats: st.stats,
    })
}

/// §4: the openings small for their part sealed, with the inside test's winding number (off
/// without it, or without `params.seal_openings`).
fn seal(
    vox: &mut Voxelization,
    flood: &mut Flood,
    tree: Option<&LazyWindingTree>,
    params: &Params,
    st: &mut Stages,
) -> Sealing {
    match tree {
        Some(tree) if params.seal_openings => {
            let sealing = seal_openings(vox, flood, tree, params.resolution);
            st.done("seal");
            sealing
        }
        _ => Sealing::default(),
    }
}

/// §6, first step (stage "inside"): the enclosed regions decided solid or air by the winding
/// number, air added to the outside; a sealed region must read as solid here too (§4), or it
/// is unsealed. Without the test (`Params::inside_test` false; on by default) every enclosed
/// region stays solid, which is the conversion without the test, bit for bit.
fn enclosed_regions(
    tree: Option<&LazyWindingTree>,
    vox: &Voxelization,
    flood: &mut Flood,
    band: &Band,
    sealing: &Sealing,
    st: &mut Stages,
) -> Regions {
    let Some(tree) = tree else {
        return Regions::default();
    };
    let mut regions = classify_regions(&vox.walls, flood, band, tree);
    st.stats.sealed_pockets = regions.unseal_unless_solid(&vox.walls, &sealing.seeds);
    mark_air(flood, &vox.walls, &regions);
    let counts = regions.counts();
    st.stats.enclosed_regions = counts.regions;
    st.stats.air_regions = counts.air;
    st.stats.ambiguous_regions = counts.ambiguous;
    st.done("inside");
    regions
}

/// §7 (stage "sign"): every core vertex's side, then its thin-shell flag. Between the two,
/// §6's second step (stage "inside"): the vertices sealed in on every side decided by the
/// winding number, and the wholly nested regions. Without the test, sealed vertices are
/// outside and nothing is nested.
fn sign(
    tree: Option<LazyWindingTree>,
    band: &Band,
    vox: &Voxelization,
    flood: &Flood,
    regions: &Regions,
    n: u32,
    st: &mut Stages,
) -> CoreSigns {
    let (touches, mut side) = vertex_sides(band, vox, flood);
    st.done("sign");
    let nesting = match tree {
        Some(tree) => {
            let sealed = decide_sealed(band, vox, &mut side, &tree, n);
            st.stats.thin_parts = sealed.thin_parts;
            st.stats.shelled_thin_parts = sealed.shelled_parts + sealed.shallow;
            st.stats.overlap_groups = sealed.overlaps;
            drop(tree);
            let nesting = Nesting::new(band, vox, &side, regions);
            st.done("inside");
            nesting
        }
        None => {
            sealed_to_outside(&mut side);
            Nesting::default()
        }
    };
    let core_signs = compute_signs(band, vox, touches, side, &nesting);
    st.done("sign");
    core_signs
}
