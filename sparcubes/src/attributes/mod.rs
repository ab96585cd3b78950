//! Appearance sampled at the active cells: base colour, metallic, roughness and alpha for
//! every row of [`SparseCubes::cells`] (docs/ALGORITHM.md, "After the conversion: attributes").
//!
//! Each source triangle is cut into the cells it crosses ([`clip`]); a piece inside an active
//! cell adds its values, taken at its centroid with the textures filtered over its own
//! footprint in texture space ([`mips`], [`shade`]), weighted by its area. A cell's value is
//! the area-weighted mean over the source surface inside it: base colour averaged in linear
//! light and stored as sRGB bytes, metallic, roughness and alpha as bytes of their [0, 1]
//! values. A cell no source triangle crosses (a thin shell's far wall, a sealed opening, a
//! filled hole) takes the values at the closest point of the source surface to its centre,
//! filtered over one cell's area.
//!
//! Determinism: triangles are processed in fixed batches, each batch's pieces computed in
//! parallel and collected in triangle order, then added to the cells one after another in that
//! order; the closest-point queries are thread-independent ([`crate::queries::closest`]). The bytes do
//! not depend on the thread count.

pub mod clip;
pub mod mips;
pub mod shade;
pub mod vertex_colours;

use crate::cubes::SparseCubes;
use crate::materials::Appearance;
use crate::mesh::TriMesh;
use crate::queries::closest::TriangleIndex;
use mips::{linear_to_srgb, to_byte};
use rayon::prelude::*;
use shade::{Shader, Values};

/// The attributes of the active cells, one entry per row of `cells`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CellAttributes {
    /// Base colour, sRGB bytes.
    pub base_color: Vec<[u8; 3]>,
    /// Metallic, 0–255 for 0–1.
    pub metallic: Vec<u8>,
    /// Roughness, 0–255 for 0–1.
    pub roughness: Vec<u8>,
    /// Alpha (coverage), 0–255 for 0–1.
    pub alpha: Vec<u8>,
    /// Cells that took the closest surface point's values (no source triangle crosses them).
    pub nearest_cells: u64,
}

/// Triangles whose pieces are computed in parallel before they are added, in order.
const BATCH: usize = 1 << 16;
/// Triangles per parallel task in a batch.
const CHUNK: usize = 256;

/// One piece's contribution: the cell (its row), the area and the values.
type Piece = (u32, f64, Values);

/// The source surface in grid coordinates, with the triangles that can carry a value
/// (indices in range, finite corners, positive area) and their areas.
struct GridSurface {
    positions: Vec<[f64; 3]>,
    /// (triangle index in the appearance, its area).
    triangles: Vec<(usize, f64)>,
}

impl GridSurface {
    fn new(app: &Appearance, cubes: &SparseCubes) -> Self {
        let s = &app.surface;
        let n = cubes.resolution;
        let positions: Vec<[f64; 3]> = s
            .positions
            .iter()
            .map(|p| cubes.normalization.source_to_grid(p.map(f64::from), n))
            .collect();
        let triangles = s
            .triangles
            .iter()
            .enumerate()
            .filter_map(|(t, tri)| {
                let c = tri.map(|i| positions.get(i as usize).copied());
                let [Some(a), Some(b), Some(c)] = c else {
                    return None;
                };
                let area = crate::vec3::norm(crate::vec3::cross(
                    crate::vec3::sub(b, a),
                    crate::vec3::sub(c, a),
                )) * 0.5;
                (area.is_finite() && area > 0.0).then_some((t, area))
            })
            .collect();
        Self {
            positions,
            triangles,
        }
    }

    fn corners(&self, app: &Appearance, t: usize) -> [[f64; 3]; 3] {
        app.surface.triangles[t].map(|i| self.positions[i as usize])
    }
}

/// Samples the appearance `app` (its surface in the source frame) at the active cells of
/// `cubes`.
pub fn sample(cubes: &SparseCubes, app: &Appearance) -> CellAttributes {
    let grid = GridSurface::new(app, cubes);
    let shader = Shader::new(app);
    let mut sums = vec![[0.0f64; 7]; cubes.cells.len()];
    for batch in grid.triangles.chunks(BATCH) {
        let pieces: Vec<Vec<Piece>> = batch
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut out = Vec::new();
                for &(t, area) in chunk {
                    triangle_pieces(&grid, app, &shader, cubes, (t, area), &mut out);
                }
                out
            })
            .collect();
        for (cell, w, v) in pieces.into_iter().flatten() {
            let s = &mut sums[cell as usize];
            s[0] += w;
            for k in 0..6 {
                s[k + 1] += w * v[k] as f64;
            }
        }
    }
    let mut values: Vec<Option<Values>> = sums
        .iter()
        .map(|s| (s[0] > 0.0).then(|| std::array::from_fn(|k| (s[k + 1] / s[0]) as f32)))
        .collect();
    let nearest_cells = fill_nearest(&grid, app, &shader, cubes, &mut values);
    encode(&values, nearest_cells)
}

/// Appends the pieces of triangle `t` (of area `area`) that lie in active cells.
fn triangle_pieces(
    grid: &GridSurface,
    app: &Appearance,
    shader: &Shader,
    cubes: &SparseCubes,
    (t, area): (usize, f64),
    out: &mut Vec<Piece>,
) {
    let density = shader.uv_density(t, area);
    let n = cubes.resolution as i64;
    clip::for_each_piece(grid.corners(app, t), |cell, a, bary| {
        if cell.iter().any(|&c| c < 0 || c >= n) {
            return;
        }
        let key = cell.map(|c| c as u16);
        if let Ok(row) = cubes.cells.binary_search(&key) {
            out.push((row as u32, a, shader.at(t, bary, a, density)));
        }
    });
}

/// Gives every cell without a value the values at the source surface's closest point to its
/// centre; returns how many there were.
fn fill_nearest(
    grid: &GridSurface,
    app: &Appearance,
    shader: &Shader,
    cubes: &SparseCubes,
    values: &mut [Option<Values>],
) -> u64 {
    let empty: Vec<usize> = (0..values.len()).filter(|&i| values[i].is_none()).collect();
    if empty.is_empty() {
        return 0;
    }
    let mesh = TriMesh::new(
        grid.positions.iter().map(|p| p.map(|x| x as f32)).collect(),
        grid.triangles
            .iter()
            .map(|&(t, _)| app.surface.triangles[t])
            .collect(),
    );
    let fallback: Values = [0.0; 6];
    if mesh.triangles.is_empty() {
        for &i in &empty {
            values[i] = Some(fallback);
        }
        return empty.len() as u64;
    }
    let index = TriangleIndex::new(&mesh);
    let centres: Vec<[f64; 3]> = empty
        .iter()
        .map(|&i| cubes.cells[i].map(|c| c as f64 + 0.5))
        .collect();
    let found = index.closest_batch(&centres);
    let filled: Vec<Values> = found
        .par_iter()
        .map(|c| {
            let (t, area) = grid.triangles[c.triangle as usize];
            let bary = barycentric(c.point, grid.corners(app, t));
            shader.at(t, bary, 1.0, shader.uv_density(t, area))
        })
        .collect();
    for (&i, v) in empty.iter().zip(filled) {
        values[i] = Some(v);
    }
    empty.len() as u64
}

/// Barycentric coordinates of `p` (on the triangle's plane) in triangle `tri`.
fn barycentric(p: [f64; 3], tri: [[f64; 3]; 3]) -> [f64; 3] {
    use crate::vec3::{dot, sub};
    let (e0, e1, ep) = (sub(tri[1], tri[0]), sub(tri[2], tri[0]), sub(p, tri[0]));
    let (d00, d01, d11) = (dot(e0, e0), dot(e0, e1), dot(e1, e1));
    let (d20, d21) = (dot(ep, e0), dot(ep, e1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= 0.0 || !den.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0 - v);
    [1.0 - v - w, v, w]
}

/// The values as bytes (base colour encoded to sRGB).
fn encode(values: &[Option<Values>], nearest_cells: u64) -> CellAttributes {
    let mut out = CellAttributes {
        nearest_cells,
        ..Default::default()
    };
    for v in values {
        let v = v.unwrap_or([0.0; 6]);
        out.base_color
            .push([0, 1, 2].map(|c| to_byte(linear_to_srgb(v[c]))));
        out.metallic.push(to_byte(v[3]));
        out.roughness.push(to_byte(v[4]));
        out.alpha.push(to_byte(v[5]));
    }
    out
}
