//! The conversion driver: the stages of docs/ALGORITHM.md (§1–6), top to bottom, each a free
//! function.

use crate::error::{Error, Result};
use crate::grid::cubes::SparseCubes;
use crate::grid::normalization::Normalization;
use crate::grid::{
    difference, dilate, for_each_bit, merge_masks, window_index, BrickMask, BrickSet, Dilation,
    NO_ID,
};
use crate::mesh::GridMesh;
use crate::mesh::TriMesh;
use crate::params::Params;
use crate::queries::winding::LazyWindingTree;
use crate::stages::band::{compute_band, triangle_planes, Band, CORE_REACH, REACH};
use crate::stages::deform::{compute_field, Field};
use crate::stages::flood::flood_outside;
use crate::stages::inside::classify::classify_regions;
use crate::stages::inside::nesting::Nesting;
use crate::stages::inside::regions::{mark_air, Regions};
use crate::stages::inside::sealed::decide_sealed;
use crate::stages::refine::{refine, RefineStats};
use crate::stages::ring::ring_cells;
use crate::stages::seal::{seal_openings, Sealing};
use crate::stages::sign::{compute_signs, ring_signs, sealed_to_outside, vertex_sides};
use crate::stages::voxelize::voxelize;
use rayon::prelude::*;
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
    /// Surface-free cells next to the walls that got a band of their own ([`crate::stages::ring`]).
    pub ring_cells: u64,
    /// Active vertices stored.
    pub active_vertices: u64,
    /// Active cells stored.
    pub active_cells: u64,
    /// Stored vertices that belong to a thin shell around an open part.
    pub shell_vertices: u64,
    /// Enclosed regions: connected sets of surface-free cells the outside flood cannot reach
    /// ([`crate::stages::inside`]).
    pub enclosed_regions: u64,
    /// Enclosed regions the winding number found to be air (treated as outside).
    pub air_regions: u64,
    /// Enclosed regions whose winding number was ambiguous (kept solid).
    pub ambiguous_regions: u64,
    /// Closed parts thinner than about two cells, found inside by the winding number (groups
    /// of sealed vertices joined with their 26 neighbours, [`crate::stages::inside::sealed::decide_sealed`]).
    pub thin_parts: u64,
    /// Sealed parts left to the thin shell: found inside by the winding number but too thin
    /// somewhere for the grid (under a cell), or nowhere 0.3 voxel deep (these are shelled
    /// without asking the winding number, so the count includes any such pocket).
    pub shelled_thin_parts: u64,
    /// Regions sealed behind small openings and kept solid: nearly closed parts whose
    /// openings the walls grown at the sealing scale close ([`crate::stages::seal`]), read as solid by
    /// the winding number on the coarse grid and again as enclosed regions (§2b).
    pub sealed_pockets: u64,
    /// Groups of sealed vertices inside two closed surfaces or more: closed parts overlapping
    /// by less than the grid resolves, left outside so both keep their surfaces
    /// ([`crate::stages::inside::sealed::OVERLAP_FROM`]).
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

struct Stages {
    stats: ConvertStats,
    last: Instant,
}

impl Stages {
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

/// The mesh in grid coordinates, without zero-area triangles.
fn to_grid(mesh: &TriMesh, norm: &Normalization, n: u32) -> (GridMesh, u64) {
    let verts: Vec<[f64; 3]> = mesh
        .positions
        .iter()
        .map(|p| norm.source_to_grid([p[0] as f64, p[1] as f64, p[2] as f64], n))
        .collect();
    let mut grid = GridMesh {
        verts,
        tris: Vec::with_capacity(mesh.triangles.len()),
    };
    let mut degenerate = 0;
    for &t in &mesh.triangles {
        grid.tris.push(t);
        let [a, b, c] = grid.tri(grid.tris.len() - 1);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let nrm = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        if nrm == [0.0; 3] {
            grid.tris.pop();
            degenerate += 1;
        }
    }
    (grid, degenerate)
}

/// Tag of a ring-band vertex number in the assembly's id list (core numbers are below it).
const RING_TAG: u32 = 1 << 31;

/// Vertices with their φ: a band and its `sdf` (parallel to the band's vertices).
type Values<'a> = (&'a Band, &'a [f32]);

/// The cells of `cells` with a sign change among their corners, per brick (sorted keys).
/// Every corner of every cell is a vertex of `core` or of `ring`.
fn sign_changes(cells: &BrickSet, core: Values, ring: Option<Values>) -> Vec<(u32, BrickMask)> {
    (0..cells.keys.len())
        .into_par_iter()
        .map_init(
            || (Box::new([NO_ID; 729]), Box::new([NO_ID; 729])),
            |(core_ids, ring_ids), s| {
                let b = cells.index.coord(cells.keys[s] as usize);
                core.0.verts.fill_window(b, core_ids);
                if let Some(ring) = ring {
                    ring.0.verts.fill_window(b, ring_ids);
                }
                let phi = |w: usize| -> Option<f32> {
                    match (core_ids[w], ring) {
                        (NO_ID, Some(ring)) if ring_ids[w] != NO_ID => {
                            Some(ring.1[ring_ids[w] as usize])
                        }
                        (NO_ID, _) => None,
                        (i, _) => Some(core.1[i as usize]),
                    }
                };
                let mut keep = [0u64; 8];
                for_each_bit(&cells.masks[s], |x, y, z| {
                    let (mut neg, mut pos) = (false, false);
                    for d in 0..8u32 {
                        let w = window_index(x + (d & 1), y + ((d >> 1) & 1), z + (d >> 2));
                        let Some(v) = phi(w) else {
                            return;
                        };
                        if v < 0.0 {
                            neg = true;
                        } else {
                            pos = true;
                        }
                    }
                    if neg && pos {
                        keep[z as usize] |= 1u64 << (x + 8 * y);
                    }
                });
                (cells.keys[s], keep)
            },
        )
        .collect()
}

/// Longest piece, in voxels, the winding tree cuts triangles into ([`crate::queries::winding`]): 32
/// voxels, or 1/32 of the grid at resolutions above 1024, so the number of pieces does not
/// grow with the resolution. 8 voxels gave the same outputs on the dev corpus at 256³ but
/// up to 50 times as many pieces as triangles (large flat faces), and cutting, sorting and
/// summing them was most of the inside test's time on such meshes; 16, 32 and 64 gave the
/// same bytes and about half the time of 8 (docs/QUALITY.md, issue 15).
fn winding_piece(n: u32) -> f64 {
    (n as f64 / 32.0).max(32.0)
}

/// Checks that a mesh is sanitised (indices in range, finite coordinates, an extent the grid
/// can hold) and returns its bounds.
fn checked_bounds(mesh: &TriMesh) -> Result<([f64; 3], [f64; 3])> {
    if let Some(bad) = mesh
        .triangles
        .iter()
        .flatten()
        .find(|&&i| i as usize >= mesh.positions.len())
    {
        return Err(Error::InvalidParams(format!(
            "mesh has index {bad} but only {} vertices (sanitise it first)",
            mesh.positions.len()
        )));
    }
    if mesh.positions.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::InvalidParams(
            "mesh has non-finite coordinates (sanitise it first)".into(),
        ));
    }
    let bounds = mesh.bounds().ok_or_else(|| Error::EmptyMesh {
        context: "convert".into(),
        reason: "no triangles".into(),
    })?;
    crate::grid::normalization::check_extent(bounds, "convert")?;
    Ok(bounds)
}

/// One band's values as the assembly reads them: its field and its thin-shell flags.
#[derive(Clone, Copy)]
struct BandSide<'a> {
    field: &'a Field,
    thin: &'a [bool],
}

/// The stored cubes: each active vertex's φ (and δ when `params.deform`) from the core band,
/// or from the ring's band where its id carries `RING_TAG`; returns them with the count of
/// thin-shell vertices among them.
fn assemble(
    coords: Vec<[u16; 3]>,
    ids: &[u32],
    kept: BrickSet,
    core: BandSide<'_>,
    ring: BandSide<'_>,
    normalization: Normalization,
    params: &Params,
) -> (SparseCubes, u64) {
    let source = |i: u32| -> (BandSide<'_>, usize) {
        if i & RING_TAG == 0 {
            (core, i as usize)
        } else {
            (ring, (i & !RING_TAG) as usize)
        }
    };
    let cubes = SparseCubes {
        resolution: params.resolution,
        normalization,
        coords,
        sdf: ids
            .par_iter()
            .map(|&i| {
                let (b, j) = source(i);
                b.field.sdf[j]
            })
            .collect(),
        deformation: if params.deform {
            ids.par_iter()
                .map(|&i| {
                    let (b, j) = source(i);
                    b.field.deformation_at(j)
                })
                .collect()
        } else {
            vec![[0.0; 3]; ids.len()]
        },
        cells: kept.sorted_members(),
    };
    let shell_vertices = ids
        .par_iter()
        .filter(|&&i| {
            let (b, j) = source(i);
            b.thin[j]
        })
        .count() as u64;
    (cubes, shell_vertices)
}

/// The ring's cells with the cells the caps of sealed openings run through (§3b): surface-free
/// cells where a sealed pocket meets the outside, whose corners need φ as the ring's do.
fn with_caps(rings: BrickSet, caps: Vec<(u32, BrickMask)>, n: u32) -> BrickSet {
    if caps.is_empty() {
        return rings;
    }
    let keyed = rings.keys.into_iter().zip(rings.masks).collect();
    BrickSet::from_masks(n, merge_masks(keyed, caps))
}

/// Converts a sanitised mesh into sparse cubes (docs/ALGORITHM.md §1–6; extraction, §7, is
/// [`crate::extract()`]).
pub fn convert(mesh: &TriMesh, params: &Params) -> Result<Conversion> {
    params.validate()?;
    let n = params.resolution;
    let mut st = Stages {
        stats: ConvertStats {
            input_faces: mesh.triangles.len() as u64,
            input_vertices: mesh.positions.len() as u64,
            ..Default::default()
        },
        last: Instant::now(),
    };
    let bounds = checked_bounds(mesh)?;
    let norm = Normalization::fit_span(bounds, n, params.span());
    let (grid, degenerate) = to_grid(mesh, &norm, n);
    st.stats.degenerate_faces = degenerate;
    if grid.tris.is_empty() {
        return Err(Error::EmptyMesh {
            context: "convert".into(),
            reason: format!("all {degenerate} triangles have zero area"),
        });
    }
    st.done("normalize");

    let mut vox = voxelize(&grid, n);
    st.stats.wall_cells = vox.walls.len();
    st.done("voxelize");
    let mut flood = flood_outside(&vox.walls);
    st.done("flood");
    // The inside test's winding number (§2b), built on first use; the sealing (§3b) asks it
    // about the pockets it finds.
    let tree = params
        .inside_test
        .then(|| LazyWindingTree::new(&grid, winding_piece(n)));
    let sealing = match &tree {
        Some(tree) if params.seal_openings => {
            let sealing = seal_openings(&mut vox, &mut flood, tree, n);
            st.done("seal");
            sealing
        }
        _ => Sealing::default(),
    };
    let planes = triangle_planes(&grid);
    let core_verts = dilate(&vox.walls, n, Dilation::Corners);
    let band = compute_band(&grid, &planes, core_verts, CORE_REACH);
    st.done("band");
    // The inside test (stage "inside"): enclosed regions decided solid or air by the winding
    // number, air added to the outside; later, the vertices sealed inside thin parts.
    // Off (`Params::inside_test` false; on by default): every enclosed region stays solid, no vertex
    // is sealed and nothing is nested, which is the conversion without the test, bit for bit.
    let regions = match &tree {
        Some(tree) => {
            let mut regions = classify_regions(&vox.walls, &flood, &band, tree);
            // A sealed region must read as solid here too (§3b), or it is unsealed.
            st.stats.sealed_pockets = regions.unseal_unless_solid(&vox.walls, &sealing.seeds);
            mark_air(&mut flood, &vox.walls, &regions);
            let counts = regions.counts();
            st.stats.enclosed_regions = counts.regions;
            st.stats.air_regions = counts.air;
            st.stats.ambiguous_regions = counts.ambiguous;
            st.done("inside");
            regions
        }
        None => Regions::default(),
    };
    let (touches, mut side) = vertex_sides(&band, &vox, &flood);
    st.done("sign");
    let nesting = match tree {
        Some(tree) => {
            let sealed = decide_sealed(&band, &vox, &mut side, &tree, n);
            st.stats.thin_parts = sealed.thin_parts;
            st.stats.shelled_thin_parts = sealed.shelled_parts + sealed.shallow;
            st.stats.overlap_groups = sealed.overlaps;
            drop(tree);
            let nesting = Nesting::new(&band, &vox, &side, &regions);
            st.done("inside");
            nesting
        }
        None => {
            sealed_to_outside(&mut side);
            Nesting::default()
        }
    };
    let core_signs = compute_signs(&band, &vox, touches, side, &nesting);
    let signs = &core_signs.signs;
    st.done("sign");
    let field = compute_field(&band, signs, params);
    st.done("deform");
    let rings = with_caps(
        ring_cells(&band, &core_signs, &field.sdf, &vox.walls, &flood, n),
        sealing.caps,
        n,
    );
    // The ring's own vertices: corners of ring cells that are not in the core band.
    let ring_verts = difference(&dilate(&rings, n, Dilation::Corners), &band.verts.set, n);
    let ring = compute_band(&grid, &planes, ring_verts, REACH);
    let ring_signs = ring_signs(&ring, &vox.walls, &flood, &core_signs);
    let ring_field = compute_field(&ring, &ring_signs, params);
    st.stats.ring_cells = rings.len();
    st.stats.band_vertices = (band.verts.len + ring.verts.len) as u64;
    if band.verts.len >= RING_TAG as usize || ring.verts.len >= RING_TAG as usize {
        return Err(Error::InvalidParams(format!(
            "band of {} vertices is too large to number",
            band.verts.len.max(ring.verts.len)
        )));
    }
    st.done("ring");

    // Keep the candidate cells (wall cells and ring cells, disjoint) with a sign change (φ < 0
    // is inside, φ ≥ 0 outside) and their corners; no cell outside them has one (see
    // `crate::stages::ring`), so the result is closed.
    let core = (&band, &field.sdf[..]);
    let kept = merge_masks(
        sign_changes(&vox.walls, core, None),
        sign_changes(&rings, core, Some((&ring, &ring_field.sdf[..]))),
    );
    let kept = BrickSet::from_masks(n, kept);
    // The stored vertices are exactly the corners of the kept cells, each in the core band or
    // the ring's.
    let used = dilate(&kept, n, Dilation::Corners);
    let vertex_coords = used.sorted_members();
    let ids: Vec<u32> = vertex_coords
        .par_iter()
        .map(|c| {
            let c = [c[0] as i64, c[1] as i64, c[2] as i64];
            band.verts
                .id(c)
                .or_else(|| ring.verts.id(c).map(|i| i | RING_TAG))
                .unwrap_or(NO_ID)
        })
        .collect();
    if ids.contains(&NO_ID) {
        return Err(Error::InvalidParams(
            "internal: a corner of an active cell is outside the band".into(),
        ));
    }
    let core = BandSide {
        field: &field,
        thin: &signs.thin,
    };
    let outer = BandSide {
        field: &ring_field,
        thin: &ring_signs.thin,
    };
    let (mut cubes, shell_vertices) =
        assemble(vertex_coords, &ids, kept, core, outer, norm, params);
    st.stats.shell_vertices = shell_vertices;
    st.stats.active_vertices = cubes.coords.len() as u64;
    st.stats.active_cells = cubes.cells.len() as u64;
    st.done("assemble");
    if let Some(settings) = &params.refine {
        // Thin-shell vertices stay: their surface is an offset of an open sheet by design.
        let free: Vec<bool> = ids
            .par_iter()
            .map(|&i| match i & RING_TAG {
                0 => !signs.thin[i as usize],
                _ => !ring_signs.thin[(i & !RING_TAG) as usize],
            })
            .collect();
        let stats = refine(&mut cubes, &grid, &free, settings, params.deform_max);
        st.stats.refine = Some(stats);
        st.done("refine");
    }
    Ok(Conversion {
        cubes,
        stats: st.stats,
    })
}
