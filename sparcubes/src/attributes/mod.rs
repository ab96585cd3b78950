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
//! The cells are cut into parts of whole x slices ([`parts`]); each part, in parallel with
//! the others, adds the pieces of the triangles that reach it into its own cells' sums, gives
//! the cells no piece reached their closest point's values and encodes its bytes, so only
//! one part's sums are alive per thread (the stage holds the bytes and a few MiB, not sums
//! for every cell at once). A closest point comes from the triangles crossing the 27 cells
//! around the cell where that makes it certain ([`crossings`]: the pieces' cells, noted while
//! cutting), else from a search of the whole surface ([`nearest`]).
//!
//! Determinism: the parts depend on the cells alone, a cell's pieces are added in triangle
//! order and within a triangle in piece order, and the closest-point answers of a part depend
//! on its cells and the surface only (among equally near triangles the crossings take the
//! first in the surface's order, the whole-surface search the first it meets, which does not
//! depend on the threads: [`crate::queries::closest`]). The bytes do not depend on the thread
//! count.

pub mod clip;
pub mod crossings;
pub mod mips;
pub mod nearest;
pub mod parts;
pub mod shade;
pub mod surface;
pub mod vertex_colours;

use crate::colour::{to_byte, SrgbBytes};
use crate::cubes::{gallop, SparseCubes};
use crate::materials::Appearance;
use crossings::Crossings;
use nearest::{LastShading, Nearest};
use parts::Part;
use rayon::prelude::*;
use shade::{Shader, Values};
use surface::GridSurface;

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

impl CellAttributes {
    /// No rows yet, room for `rows`.
    fn with_capacity(rows: usize) -> Self {
        Self {
            base_color: Vec::with_capacity(rows),
            metallic: Vec::with_capacity(rows),
            roughness: Vec::with_capacity(rows),
            alpha: Vec::with_capacity(rows),
            nearest_cells: 0,
        }
    }
}

/// A cell's running sums: the area, then the area-weighted values.
type Sums = [f64; 7];

/// Samples the appearance `app` (its surface in the source frame) at the active cells of
/// `cubes`.
pub fn sample(cubes: &SparseCubes, app: &Appearance) -> CellAttributes {
    let surface = GridSurface::new(app, cubes);
    let shader = Shader::new(app);
    let nearest = Nearest::new(&surface, &shader);
    let srgb = SrgbBytes::new();
    let mut parts = parts::partition(&cubes.cells);
    // A part also gets the triangles of the slice on either side, which its first and last
    // slices' cells may need for their closest points (crossings.rs).
    let spans = surface.triangles.iter().map(|&(t, _)| {
        let (x0, x1) = clip::x_span(surface.corners(t));
        (x0 - 1, x1 + 1)
    });
    parts::assign(&mut parts, spans);
    let done: Vec<CellAttributes> = parts
        .par_iter()
        .map(|part| {
            let cells = &cubes.cells[part.rows.clone()];
            let (mut sums, mut crossings) = part_sums(&surface, &shader, cells, part);
            let nearest_cells = fill_nearest(&nearest, &mut crossings, cells, part, &mut sums);
            encode(&sums, nearest_cells, &srgb)
        })
        .collect();
    concatenate(done, cubes.cells.len())
}

/// The sums of the part's `cells` (its rows) over the pieces of its triangles inside them,
/// added in triangle order and, within a triangle, in piece order; and every piece's cell
/// and triangle in the part's slices, active or not.
fn part_sums(
    surface: &GridSurface,
    shader: &Shader,
    cells: &[[u16; 3]],
    part: &Part,
) -> (Vec<Sums>, Crossings) {
    let mut sums = vec![[0.0f64; 7]; cells.len()];
    let mut crossings = Crossings::new(part.xs);
    for &j in &part.triangles {
        let (t, area) = surface.triangles[j as usize];
        let shading = shader.prepare(t, shader.uv_density(t, area));
        // The pieces' keys rise (clip::for_each_piece), so one cursor walks the rows forward.
        let mut cursor = 0;
        clip::for_each_piece_in(surface.corners(t), part.xs, |cell, a, bary| {
            crossings.record(cell, j);
            let Some(key) = cell_key(cell) else {
                return;
            };
            cursor = gallop(cells, cursor, key);
            if cells.get(cursor) == Some(&key) {
                let v = shading.at(bary, a);
                let s = &mut sums[cursor];
                s[0] += a;
                for k in 0..6 {
                    s[k + 1] += a * v[k] as f64;
                }
            }
        });
    }
    (sums, crossings)
}

/// The key of a cell of the grid's index range, `None` outside it.
#[inline]
fn cell_key(cell: [i64; 3]) -> Option<[u16; 3]> {
    let inside = |c: i64| (0..=i64::from(u16::MAX)).contains(&c);
    (inside(cell[0]) && inside(cell[1]) && inside(cell[2])).then(|| cell.map(|c| c as u16))
}

/// Gives every cell no piece reached the values at the source surface's closest point to
/// its centre, as one piece of unit area: from the `crossings` around it where they make the
/// answer certain, else from the whole surface. Returns how many cells there were.
fn fill_nearest(
    nearest: &Nearest,
    crossings: &mut Crossings,
    cells: &[[u16; 3]],
    part: &Part,
    sums: &mut [Sums],
) -> u64 {
    let empty: Vec<usize> = (0..sums.len()).filter(|&i| sums[i][0] <= 0.0).collect();
    let count = empty.len() as u64;
    if empty.is_empty() {
        return 0;
    }
    let rest = if crossings.worth_sorting_for(empty.len()) {
        fill_from_crossings(nearest, crossings, cells, part, &empty, sums)
    } else {
        empty
    };
    let values = nearest.values_at(rest.iter().map(|&i| cells[i]));
    for (&i, v) in rest.iter().zip(values) {
        sums[i] = one_piece(v);
    }
    count
}

/// Gives the `empty` cells whose closest point the crossings around them make certain its
/// values (crossings.rs); returns the others.
fn fill_from_crossings(
    nearest: &Nearest,
    crossings: &mut Crossings,
    cells: &[[u16; 3]],
    part: &Part,
    empty: &[usize],
    sums: &mut [Sums],
) -> Vec<usize> {
    let surface = nearest.surface();
    let (first, last) = part.xs;
    if empty.iter().any(|&i| i64::from(cells[i][0]) == first) {
        crossings.cover(first - 1, surface, &part.triangles);
    }
    if empty.iter().any(|&i| i64::from(cells[i][0]) == last) {
        crossings.cover(last + 1, surface, &part.triangles);
    }
    crossings.sort();
    let mut walker = crossings.walker();
    let mut rest = Vec::new();
    let mut last = LastShading::default();
    for &i in empty {
        match walker.closest(cells[i], surface) {
            Some(found) => {
                sums[i] = one_piece(nearest.values_on(found.triangle, found.point, &mut last))
            }
            None => rest.push(i),
        }
    }
    rest
}

/// The sums of one piece of unit area with values `v` (their means are `v` exactly).
fn one_piece(v: Values) -> Sums {
    [1.0, v[0], v[1], v[2], v[3], v[4], v[5]].map(f64::from)
}

/// The cells' means as bytes (base colour encoded to sRGB).
fn encode(sums: &[Sums], nearest_cells: u64, srgb: &SrgbBytes) -> CellAttributes {
    let mut out = CellAttributes {
        nearest_cells,
        ..CellAttributes::with_capacity(sums.len())
    };
    for s in sums {
        let v: Values = if s[0] > 0.0 {
            std::array::from_fn(|k| (s[k + 1] / s[0]) as f32)
        } else {
            [0.0; 6]
        };
        out.base_color.push([0, 1, 2].map(|c| srgb.byte(v[c])));
        out.metallic.push(to_byte(v[3]));
        out.roughness.push(to_byte(v[4]));
        out.alpha.push(to_byte(v[5]));
    }
    out
}

/// The parts' attributes, in part order, as one set of `rows` rows.
fn concatenate(parts: Vec<CellAttributes>, rows: usize) -> CellAttributes {
    let mut out = CellAttributes::with_capacity(rows);
    for p in parts {
        out.base_color.extend(p.base_color);
        out.metallic.extend(p.metallic);
        out.roughness.extend(p.roughness);
        out.alpha.extend(p.alpha);
        out.nearest_cells += p.nearest_cells;
    }
    out
}
