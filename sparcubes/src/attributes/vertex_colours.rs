//! Colours for the output mesh's vertices, from the attributes of the active cells: what
//! `convert --attributes` and `show` write where the output format holds colours, so that a
//! person can look at what the cells carry.

use super::CellAttributes;
use crate::cubes::SparseCubes;
use crate::mesh::TriMesh;
use rayon::prelude::*;

/// The colour of a vertex no active cell is near (none is, on a mesh extracted from these
/// cubes): mid grey, opaque.
pub const NO_CELL: [u8; 4] = [128, 128, 128, 255];

/// Each vertex of `mesh`, in the grid frame (cell `[i, j, k]` spans `[i, i + 1]` on each axis,
/// as [`crate::extract()`] returns it), gets the sRGB base colour and the alpha of the active
/// cell that holds it. A vertex outside every active cell (on a face shared with an inactive
/// one, or moved by the deformation) takes the active cell among the 27 around its own whose
/// centre is closest, the first in cell order on a tie; [`NO_CELL`] when there is none.
/// `cells` has one row per row of `cubes.cells`; the result does not depend on the threads.
pub fn vertex_colours(cubes: &SparseCubes, cells: &CellAttributes, mesh: &TriMesh) -> Vec<[u8; 4]> {
    let colour = |row: usize| -> [u8; 4] {
        match (cells.base_color.get(row), cells.alpha.get(row)) {
            (Some(&[r, g, b]), Some(&a)) => [r, g, b, a],
            _ => NO_CELL,
        }
    };
    mesh.positions
        .par_iter()
        .map(|p| cell_of(cubes, *p).map_or(NO_CELL, colour))
        .collect()
}

/// The row in `cubes.cells` of the active cell holding `p`, else of the active cell among the
/// 27 around it with the closest centre.
fn cell_of(cubes: &SparseCubes, p: [f32; 3]) -> Option<usize> {
    let last = cubes.resolution.saturating_sub(1) as f32;
    let home = p.map(|x| x.floor().clamp(0.0, last) as i64);
    let row = |c: [i64; 3]| -> Option<usize> {
        let key: [u16; 3] = [
            u16::try_from(c[0]).ok()?,
            u16::try_from(c[1]).ok()?,
            u16::try_from(c[2]).ok()?,
        ];
        cubes.cells.binary_search(&key).ok()
    };
    if let Some(r) = row(home) {
        return Some(r);
    }
    let mut best: Option<(f32, usize)> = None;
    for d in 0..27i64 {
        let c = [
            home[0] + d % 3 - 1,
            home[1] + (d / 3) % 3 - 1,
            home[2] + d / 9 - 1,
        ];
        let Some(r) = row(c) else { continue };
        let dist: f32 = (0..3).map(|a| (c[a] as f32 + 0.5 - p[a]).powi(2)).sum();
        let better = match best {
            Some((bd, br)) => dist < bd || (dist == bd && r < br),
            None => true,
        };
        if better {
            best = Some((dist, r));
        }
    }
    best.map(|(_, r)| r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Normalization;

    fn cubes(cells: Vec<[u16; 3]>) -> SparseCubes {
        SparseCubes {
            resolution: 8,
            normalization: Normalization::default(),
            coords: Vec::new(),
            sdf: Vec::new(),
            deformation: Vec::new(),
            cells,
        }
    }

    fn attributes(colours: &[[u8; 3]]) -> CellAttributes {
        CellAttributes {
            base_color: colours.to_vec(),
            metallic: vec![0; colours.len()],
            roughness: vec![0; colours.len()],
            alpha: (0..colours.len()).map(|i| 200 + i as u8).collect(),
            nearest_cells: 0,
        }
    }

    #[test]
    fn a_vertex_takes_the_cell_that_holds_it_or_the_closest_one_around_it() {
        let cubes = cubes(vec![[1, 1, 1], [2, 1, 1]]);
        let cells = attributes(&[[255, 0, 0], [0, 0, 255]]);
        let mesh = TriMesh::new(
            vec![
                [1.5, 1.5, 1.5],  // inside the first cell
                [2.25, 1.5, 1.5], // inside the second
                [3.2, 1.5, 1.5],  // in an inactive cell, next to the second
                [0.9, 1.5, 1.5],  // in an inactive cell, next to the first
                [6.5, 6.5, 6.5],  // far from both
            ],
            Vec::new(),
        );
        let got = vertex_colours(&cubes, &cells, &mesh);
        assert_eq!(
            got,
            vec![
                [255, 0, 0, 200],
                [0, 0, 255, 201],
                [0, 0, 255, 201],
                [255, 0, 0, 200],
                NO_CELL
            ]
        );
    }
}
