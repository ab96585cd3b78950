//! Stage 10: the stored cubes. The candidate cells (the wall cells and the ring's, disjoint)
//! with a sign change among their corners (φ < 0 inside, φ ≥ 0 outside) are kept, and their
//! corners, each in the core band or the ring's, are the stored vertices with their φ and
//! displacement. No cell outside the candidates has a sign change (stage 9,
//! [`crate::stages::ring`]), so the result is closed.

use crate::error::{Error, Result};
use crate::grid::cubes::SparseCubes;
use crate::grid::normalization::Normalization;
use crate::grid::{
    dilate, for_each_bit, merge_masks, window_index, BrickMask, BrickSet, Dilation, NO_ID,
};
use crate::params::Params;
use crate::stages::band::Band;
use crate::stages::deform::Field;
use crate::stages::ring::Ring;
use crate::stages::sign::Signs;
use rayon::prelude::*;

/// The core band's values: its vertices (the corners of the wall cells), their signs and
/// their field.
#[derive(Clone, Copy)]
pub struct Core<'a> {
    /// The core band.
    pub band: &'a Band,
    /// Its signs and thin-shell flags.
    pub signs: &'a Signs,
    /// Its φ and displacements.
    pub field: &'a Field,
}

/// What the assembly stored: the cubes, and for each stored vertex its number in the core
/// band or (tagged with [`RING_TAG`]) in the ring's.
pub struct Assembly {
    /// The stored cubes.
    pub cubes: SparseCubes,
    /// Per stored vertex: its band and number there.
    pub ids: Vec<u32>,
    /// Stored vertices that belong to a thin shell around an open part.
    pub shell_vertices: u64,
}

/// The stored cubes of the core band and the ring: the candidate cells with a sign change,
/// their corners, and each corner's φ (and δ when `params.deform`).
pub fn assemble(
    core: Core<'_>,
    ring: &Ring,
    walls: &BrickSet,
    normalization: Normalization,
    params: &Params,
) -> Result<Assembly> {
    let n = params.resolution;
    if core.band.verts.len >= RING_TAG as usize || ring.band.verts.len >= RING_TAG as usize {
        return Err(Error::InvalidParams(format!(
            "band of {} vertices is too large to number",
            core.band.verts.len.max(ring.band.verts.len)
        )));
    }
    let values = (core.band, &core.field.sdf[..]);
    let kept = merge_masks(
        sign_changes(walls, values, None),
        sign_changes(&ring.cells, values, Some((&ring.band, &ring.field.sdf[..]))),
    );
    let kept = BrickSet::from_masks(n, kept);
    // The stored vertices are exactly the corners of the kept cells, each in the core band or
    // the ring's.
    let vertex_coords = dilate(&kept, n, Dilation::Corners).sorted_members();
    let ids = vertex_ids(&vertex_coords, core.band, &ring.band)?;
    let core_side = BandSide {
        field: core.field,
        thin: &core.signs.thin,
    };
    let ring_side = BandSide {
        field: &ring.field,
        thin: &ring.signs.thin,
    };
    let (cubes, shell_vertices) = stored_cubes(
        vertex_coords,
        &ids,
        kept,
        core_side,
        ring_side,
        normalization,
        params,
    );
    Ok(Assembly {
        cubes,
        ids,
        shell_vertices,
    })
}

/// Each vertex's number in the core band, or in the ring's tagged with [`RING_TAG`]; an error
/// if one is in neither.
fn vertex_ids(coords: &[[u16; 3]], core: &Band, ring: &Band) -> Result<Vec<u32>> {
    let ids: Vec<u32> = coords
        .par_iter()
        .map(|c| {
            let c = [c[0] as i64, c[1] as i64, c[2] as i64];
            core.verts
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
    Ok(ids)
}

/// Per stored vertex ([`Assembly::ids`]), whether the refinement may move it: thin-shell vertices stay, their
/// surface is an offset of an open sheet by design.
pub fn free_vertices(ids: &[u32], core: &Signs, ring: &Signs) -> Vec<bool> {
    ids.par_iter()
        .map(|&i| match i & RING_TAG {
            0 => !core.thin[i as usize],
            _ => !ring.thin[(i & !RING_TAG) as usize],
        })
        .collect()
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

/// One band's values as the assembly reads them: its field and its thin-shell flags.
#[derive(Clone, Copy)]
struct BandSide<'a> {
    field: &'a Field,
    thin: &'a [bool],
}

/// The stored cubes: each active vertex's φ (and δ when `params.deform`) from the core band,
/// or from the ring's band where its id carries `RING_TAG`; returns them with the count of
/// thin-shell vertices among them.
fn stored_cubes(
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
