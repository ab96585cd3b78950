//! The conversion driver: the stages of DESIGN.md §3, top to bottom, each a free function.

use crate::band::compute_band;
use crate::cubes::SparseCubes;
use crate::deform::compute_field;
use crate::error::{Error, Result};
use crate::flood::flood_outside;
use crate::grid::{for_each_bit, window_index, NO_ID};
use crate::mesh::TriMesh;
use crate::normalize::Normalization;
use crate::params::Params;
use crate::sign::compute_signs;
use crate::voxelize::{voxelize, GridMesh};
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
    /// Band vertices whose distance was computed.
    pub band_vertices: u64,
    /// Active vertices stored.
    pub active_vertices: u64,
    /// Active cells stored.
    pub active_cells: u64,
    /// Stored vertices that belong to a thin shell around an open part.
    pub shell_vertices: u64,
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
    fn done(&mut self, name: &'static str) {
        let now = Instant::now();
        self.stats
            .stage_seconds
            .push((name, (now - self.last).as_secs_f64()));
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

#[inline]
fn sort_key(c: [u32; 3]) -> u64 {
    ((c[0] as u64) << 32) | ((c[1] as u64) << 16) | c[2] as u64
}

/// Converts a sanitised mesh into sparse cubes (DESIGN.md §3, steps 1–5).
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
    let norm = Normalization::fit(bounds, n, params.margin_cells);
    let (grid, degenerate) = to_grid(mesh, &norm, n);
    st.stats.degenerate_faces = degenerate;
    if grid.tris.is_empty() {
        return Err(Error::EmptyMesh {
            context: "convert".into(),
            reason: format!("all {degenerate} triangles have zero area"),
        });
    }
    st.done("normalize");

    let vox = voxelize(&grid, n);
    st.stats.wall_cells = vox.walls.len();
    st.done("voxelize");
    let flood = flood_outside(&vox.walls);
    st.done("flood");
    let band = compute_band(&grid, &vox.walls, n);
    st.stats.band_vertices = band.verts.len as u64;
    st.done("band");
    let signs = compute_signs(&band, &vox, &flood);
    st.done("sign");
    let field = compute_field(&band, &signs, params);
    st.done("deform");

    // Keep the candidate cells with a sign change (φ < 0 is inside, φ ≥ 0 outside) and their
    // corners; the band guarantees no sign change on its border, so the result is closed.
    let cells_set = &band.cells;
    let verts = &band.verts;
    let per_brick: Vec<(Vec<[u32; 3]>, Vec<u32>)> = (0..cells_set.keys.len())
        .into_par_iter()
        .map_init(
            || Box::new([NO_ID; 729]),
            |window, s| {
                let b = cells_set.index.coord(cells_set.keys[s] as usize);
                verts.fill_window(b, window);
                let mut cells = Vec::new();
                let mut corners = Vec::new();
                for_each_bit(&cells_set.masks[s], |x, y, z| {
                    let mut ids = [0u32; 8];
                    let (mut neg, mut pos) = (false, false);
                    for (d, id) in ids.iter_mut().enumerate() {
                        let d = d as u32;
                        let i = window[window_index(x + (d & 1), y + ((d >> 1) & 1), z + (d >> 2))];
                        // Every corner of a candidate cell is a band vertex by construction.
                        if i == NO_ID {
                            return;
                        }
                        *id = i;
                        if field.sdf[i as usize] < 0.0 {
                            neg = true;
                        } else {
                            pos = true;
                        }
                    }
                    if neg && pos {
                        cells.push([b[0] * 8 + x, b[1] * 8 + y, b[2] * 8 + z]);
                        corners.extend_from_slice(&ids);
                    }
                });
                (cells, corners)
            },
        )
        .collect();
    let mut used = vec![false; verts.len];
    let mut cell_coords = Vec::new();
    for (cells, corners) in per_brick {
        cell_coords.extend(cells);
        for i in corners {
            used[i as usize] = true;
        }
    }
    cell_coords.par_sort_unstable_by_key(|&c| sort_key(c));
    let all_coords = verts.coords();
    let mut order: Vec<(u64, u32)> = (0..verts.len)
        .filter(|&i| used[i])
        .map(|i| (sort_key(all_coords[i]), i as u32))
        .collect();
    order.par_sort_unstable();
    let narrow = |c: [u32; 3]| [c[0] as u16, c[1] as u16, c[2] as u16];
    let cubes = SparseCubes {
        resolution: n,
        normalization: norm,
        coords: order
            .iter()
            .map(|&(_, i)| narrow(all_coords[i as usize]))
            .collect(),
        sdf: order.iter().map(|&(_, i)| field.sdf[i as usize]).collect(),
        deformation: order
            .iter()
            .map(|&(_, i)| field.deformation[i as usize])
            .collect(),
        cells: cell_coords.into_iter().map(narrow).collect(),
    };
    st.stats.active_vertices = cubes.coords.len() as u64;
    st.stats.active_cells = cubes.cells.len() as u64;
    st.stats.shell_vertices = order
        .iter()
        .filter(|&&(_, i)| signs.thin[i as usize])
        .count() as u64;
    st.done("assemble");
    Ok(Conversion {
        cubes,
        stats: st.stats,
    })
}
