//! The active cells cut into parts of whole x slices, each with the triangles that reach it,
//! so that each part gathers its own cells' sums with no other part writing to them.
//!
//! The cut depends on the cells alone (about [`ROWS_PER_PART`] rows a part), never on the
//! thread count, and each part's triangles keep the surface's order: a cell's sum adds its
//! pieces in the same order whatever the threads, so the bytes do not depend on them.

use std::ops::Range;

/// Rows a part holds at least (unless it is the last): it ends at the first boundary between
/// x slices after this many rows. Small enough that a part's working set (56 bytes of sums
/// a row) stays a few MiB, large enough that the parts outnumber the threads of a big grid.
pub const ROWS_PER_PART: usize = 1 << 16;

/// Whole x slices of the active cells and the triangles that reach them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Part {
    /// Its rows of the cells.
    pub rows: Range<usize>,
    /// Its first and last x slice.
    pub xs: (i64, i64),
    /// The triangles (positions in the surface's list) whose x span, as given to [`assign`],
    /// meets `xs`, in order.
    pub triangles: Vec<u32>,
}

/// The sorted `cells` cut into parts of whole x slices, without triangles yet.
pub fn partition(cells: &[[u16; 3]]) -> Vec<Part> {
    let mut parts = Vec::new();
    let mut start = 0;
    while start < cells.len() {
        let last_x = cells[(start + ROWS_PER_PART).min(cells.len()) - 1][0];
        let end = start + cells[start..].partition_point(|c| c[0] <= last_x);
        parts.push(Part {
            rows: start..end,
            xs: (i64::from(cells[start][0]), i64::from(last_x)),
            triangles: Vec::new(),
        });
        start = end;
    }
    parts
}

/// Gives each part the triangles whose x span (first and last slice, one span a triangle,
/// in the surface's order) meets its slices.
pub fn assign(parts: &mut [Part], spans: impl Iterator<Item = (i64, i64)>) {
    for (j, (x0, x1)) in spans.enumerate() {
        let first = parts.partition_point(|p| p.xs.1 < x0);
        for p in parts[first..].iter_mut().take_while(|p| p.xs.0 <= x1) {
            p.triangles.push(j as u32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cells in `slices` x slices of `per_slice` cells each.
    fn slab_cells(slices: u16, per_slice: u16) -> Vec<[u16; 3]> {
        (0..slices)
            .flat_map(|x| (0..per_slice).map(move |z| [x, 0, z]))
            .collect()
    }

    #[test]
    fn parts_hold_whole_slices_and_cover_every_row_once() {
        let cells = slab_cells(40, 5000);
        let parts = partition(&cells);
        assert!(parts.len() > 1);
        let mut next = 0;
        for p in &parts {
            assert_eq!(p.rows.start, next);
            next = p.rows.end;
            let first = cells[p.rows.start][0];
            let last = cells[p.rows.end - 1][0];
            assert_eq!(p.xs, (i64::from(first), i64::from(last)));
            assert!(p.rows.end == cells.len() || cells[p.rows.end][0] > last);
            assert!(p.rows.end == cells.len() || p.rows.len() >= ROWS_PER_PART);
        }
        assert_eq!(next, cells.len());
        assert!(partition(&[]).is_empty());
    }

    #[test]
    fn a_triangle_goes_to_every_part_its_span_meets_in_order() {
        let cells = slab_cells(40, 5000);
        let mut parts = partition(&cells);
        let spans = [(0, 0), (-5, 100), (14, 14), (39, 50), (60, 70)];
        assign(&mut parts, spans.iter().copied());
        for p in &parts {
            let expected: Vec<u32> = spans
                .iter()
                .enumerate()
                .filter(|(_, &(a, b))| a <= p.xs.1 && b >= p.xs.0)
                .map(|(j, _)| j as u32)
                .collect();
            assert_eq!(p.triangles, expected, "part {:?}", p.xs);
        }
        assert!(parts.iter().all(|p| !p.triangles.contains(&4)));
        assert!(parts.iter().all(|p| p.triangles.contains(&1)));
    }
}
