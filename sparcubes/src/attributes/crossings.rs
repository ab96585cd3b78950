//! The source triangles that cross each cell of a part's slices, sorted by cell, so that a
//! cell no triangle crosses can find the closest source point among the triangles of the 27
//! cells around it, and know when that answer is the whole surface's.
//!
//! Why: the cells that need a closest point (a thin shell's far wall, a sealed opening) lie
//! within a voxel or two of the source surface, and on sheets and thin walls they are most of
//! the cells. A search of the whole surface's tree visits every node whose box reaches the
//! query, and a sheet's few large triangles have boxes that reach everywhere (about 1.4 µs a
//! query on `Helgo_Toilets`, docs/record/PERFORMANCE-history.md); the triangles crossing the
//! cells around a cell are a handful, already known from cutting them into pieces.
//!
//! When the answer is certain: a triangle with a point nearer than 1.5 to the cell's centre
//! has a piece inside the 3 × 3 × 3 cells around it (the ball lies inside them), so the
//! nearest of the triangles crossing those cells is the surface's nearest whenever it is
//! nearer than 1.5. The crossings are those of the slices they cover (a part's own, and the
//! slice on either side where a cell of its first or last slice asks: [`Crossings::cover`];
//! a part can be a single slice), so the bound is also at most the centre's distance to the
//! ends of those slices. Beyond the bound (or when the cells around hold more than
//! 48 triangles) the caller asks the whole surface. A triangle whose pieces
//! all have no area (numerically) is not a candidate.

use super::clip;
use super::surface::GridSurface;
use crate::cubes::gallop;
use crate::mesh::triangle::closest_point_on_triangle;
use crate::vec3::dist2;

/// Distinct triangles the cells around a cell may hold for an answer from them.
const MAX_CANDIDATES: usize = 48;

/// How far from a cell's centre the 3 × 3 × 3 cells around it reach at least.
const REACH: f64 = 1.5;

/// Crossings a query may cost in sorting before the whole-surface search is the cheaper
/// way: sorting costs some tens of nanoseconds a crossing, a whole-surface query on a dense
/// mesh about a microsecond, an answer from the crossings a few hundred nanoseconds.
const WORTH: usize = 16;

/// Kept from the bound for rounding: an answer must be nearer than the bound by this much.
const SLACK: f64 = 1e-6;

/// The crossings of a run of x slices: for every piece, its cell and its triangle; once
/// sorted, each column's (x, y) crossings in rising z, found by the column's place.
///
/// Why columns: the cells around a cell are nine short runs of three, one in each of the
/// nine columns around its own, so a column's crossings are all a query reads; sorting by
/// column is a counting pass over the crossings and small sorts within each column, not one
/// sort of them all (which cost about as much as the walk: docs/record/PERFORMANCE-history.md,
/// "Fifth round").
#[derive(Debug, Default)]
pub struct Crossings {
    /// The pieces recorded, in the order recorded (emptied by [`Crossings::sort`]).
    hits: Vec<Hit>,
    /// The first and last x slice covered.
    xs: (i64, i64),
    /// The least and greatest y of the pieces recorded.
    ys: (i64, i64),
    /// After [`Crossings::sort`]: where each column's crossings start in `entries`, the
    /// columns x-major over `xs` and `ys`, and one more for the end.
    starts: Vec<u32>,
    /// After [`Crossings::sort`]: each column's `(z + 1) << 32 | triangle`, rising.
    entries: Vec<u64>,
}

/// One piece's cell and triangle (a position in the surface's list).
#[derive(Debug, Clone, Copy)]
struct Hit {
    cell: [i32; 3],
    triangle: u32,
}

/// Columns a set of crossings may sort into, beyond [`COLUMNS_PER_CROSSING`] a crossing:
/// a sparse part of a large grid has more columns than crossings, and one start a column is
/// what that costs.
const SPARE_COLUMNS: usize = 1 << 16;

/// Columns a crossing may bring (see [`SPARE_COLUMNS`]); past that the walk answers nothing
/// and the whole surface is asked.
const COLUMNS_PER_CROSSING: usize = 64;

/// A closest point found from the cells around a cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Found {
    /// The triangle (position in the surface's list).
    pub triangle: u32,
    /// The closest point on it (grid coordinates).
    pub point: [f64; 3],
}

/// Whether a cell coordinate is one whose cell, or a neighbour of one of the grid's, can be
/// recorded: from -1 to 65,536 (the cells around any cell of the grid).
#[inline]
fn fits(c: i64) -> bool {
    (-1..=i64::from(u16::MAX) + 1).contains(&c)
}

impl Crossings {
    /// None yet, for the slices `xs` (first, last), whose pieces the caller records.
    pub fn new(xs: (i64, i64)) -> Self {
        Self {
            xs,
            ys: (i64::MAX, i64::MIN),
            ..Self::default()
        }
    }

    /// Notes that triangle `j` has a piece in `cell`.
    #[inline]
    pub fn record(&mut self, cell: [i64; 3], j: u32) {
        if cell.iter().all(|&c| fits(c)) {
            self.ys = (self.ys.0.min(cell[1]), self.ys.1.max(cell[1]));
            let cell = cell.map(|c| c as i32);
            self.hits.push(Hit { cell, triangle: j });
        }
    }

    /// Also covers slice `x`, next to the first or last slice covered, cutting the
    /// `triangles` (positions in the surface's list; those that do not reach `x` add nothing)
    /// into its cells.
    pub fn cover(&mut self, x: i64, surface: &GridSurface, triangles: &[u32]) {
        if x + 1 != self.xs.0 && x - 1 != self.xs.1 {
            return;
        }
        for &j in triangles {
            let (t, _) = surface.triangles[j as usize];
            clip::for_each_piece_in(surface.corners(t), (x, x), |cell, _, _| {
                self.record(cell, j)
            });
        }
        self.xs = (self.xs.0.min(x), self.xs.1.max(x));
    }

    /// Whether answering `queries` cells from the crossings is worth sorting them: not where
    /// the crossings outnumber the queries 16 times or more (a dense mesh with few
    /// cells to fill, whose whole-surface search is quick: its triangles' boxes are small),
    /// nor where they would sort into too many columns (with room for the two slices
    /// [`Crossings::cover`] may add).
    pub fn worth_sorting_for(&self, queries: usize) -> bool {
        let xs = (self.xs.0.saturating_sub(1), self.xs.1.saturating_add(1));
        self.hits.len() < WORTH * queries && self.columns(xs).is_some()
    }

    /// The number of columns over the slices `xs` and the recorded `ys`, `None` when that is
    /// more than the crossings may bring.
    fn columns(&self, xs: (i64, i64)) -> Option<usize> {
        let n = self.hits.len();
        // Checked: before any crossing is recorded `ys` is (i64::MAX, i64::MIN), no columns
        // (a part none of whose triangles has a piece, as when a surface has none at all).
        let span = |(a, b): (i64, i64)| usize::try_from(b.checked_sub(a)?.checked_add(1)?).ok();
        let nx = span(xs)?;
        let ny = span(self.ys)?;
        let columns = nx.checked_mul(ny)?;
        let allowed = n.saturating_mul(COLUMNS_PER_CROSSING) + SPARE_COLUMNS;
        (columns <= allowed && n < u32::MAX as usize).then_some(columns)
    }

    /// Sorts the crossings by column and, within a column, by z and triangle; call once,
    /// after the last [`Crossings::record`] and [`Crossings::cover`]. Where there would be
    /// too many columns ([`Crossings::worth_sorting_for`]) the walk answers nothing.
    pub fn sort(&mut self) {
        let hits = std::mem::take(&mut self.hits);
        let Some(columns) = self.columns(self.xs).filter(|_| !hits.is_empty()) else {
            return;
        };
        let column = |h: &Hit| self.column_index(i64::from(h.cell[0]), i64::from(h.cell[1]));
        let mut starts = vec![0u32; columns + 1];
        for h in &hits {
            starts[column(h) + 1] += 1;
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        let mut next = starts.clone();
        let mut entries = vec![0u64; hits.len()];
        for h in &hits {
            let slot = &mut next[column(h)];
            entries[*slot as usize] = ((h.cell[2] + 1) as u64) << 32 | u64::from(h.triangle);
            *slot += 1;
        }
        for c in 0..columns {
            entries[starts[c] as usize..starts[c + 1] as usize].sort_unstable();
        }
        self.starts = starts;
        self.entries = entries;
    }

    /// The place of column (`x`, `y`), one inside the slices `xs` and the recorded `ys`, in
    /// x-major order.
    fn column_index(&self, x: i64, y: i64) -> usize {
        let ny = self.ys.1 - self.ys.0 + 1;
        ((x - self.xs.0) * ny + (y - self.ys.0)) as usize
    }

    /// The sorted crossings of column (`x`, `y`); none outside the columns covered.
    fn column(&self, x: i64, y: i64) -> &[u64] {
        let inside = (self.xs.0..=self.xs.1).contains(&x) && (self.ys.0..=self.ys.1).contains(&y);
        if self.starts.is_empty() || !inside {
            return &[];
        }
        let c = self.column_index(x, y);
        &self.entries[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// A walk over cells in rising order.
    pub fn walker(&self) -> Walker<'_> {
        Walker {
            crossings: self,
            last: None,
            cursors: [0; 9],
        }
    }
}

/// Closest points for cells taken in rising order, from the crossings around each.
pub struct Walker<'c> {
    crossings: &'c Crossings,
    /// The cell asked before, whose column the cursors are in.
    last: Option<[u16; 3]>,
    /// For each of the 9 columns around the cell, where its crossings from the cell's z − 1
    /// on start.
    cursors: [usize; 9],
}

impl Walker<'_> {
    /// The surface's closest point to the centre of `cell` (after any cell asked before it),
    /// when the crossings around it make it certain; `None` when the whole surface must be
    /// asked.
    pub fn closest(&mut self, cell: [u16; 3], surface: &GridSurface) -> Option<Found> {
        let centre = cell.map(|c| f64::from(c) + 0.5);
        let (first, last) = self.crossings.xs;
        let bound = REACH
            .min(centre[0] - first as f64)
            .min((last + 1) as f64 - centre[0])
            - SLACK;
        if bound <= 0.0 {
            return None;
        }
        let candidates = self.candidates(cell)?;
        let mut best: Option<(f64, Found)> = None;
        for &j in &candidates.list[..candidates.len] {
            let (t, _) = surface.triangles[j as usize];
            let point = closest_point_on_triangle(centre, &surface.corners(t));
            let d2 = dist2(point, centre);
            let better = best.is_none_or(|(b, f)| d2 < b || (d2 == b && j < f.triangle));
            if better {
                best = Some((d2, Found { triangle: j, point }));
            }
        }
        let (d2, found) = best?;
        (d2 < bound * bound).then_some(found)
    }

    /// The distinct triangles crossing the 27 cells around `cell`, `None` when there are more
    /// than [`MAX_CANDIDATES`].
    fn candidates(&mut self, cell: [u16; 3]) -> Option<Candidates> {
        let same_column = self
            .last
            .is_some_and(|l| l[0] == cell[0] && l[1] == cell[1] && l[2] <= cell[2]);
        if !same_column {
            self.cursors = [0; 9];
        }
        self.last = Some(cell);
        let mut out = Candidates {
            list: [0; MAX_CANDIDATES],
            len: 0,
        };
        let [x, y, z] = cell.map(u64::from);
        // Cells z − 1 to z + 1 are entries z to z + 2 (z shifted by one).
        let (lo, hi) = (z << 32, z + 2);
        for (k, cursor) in self.cursors.iter_mut().enumerate() {
            let (dx, dy) = (k as i64 / 3 - 1, k as i64 % 3 - 1);
            let column = self.crossings.column(x as i64 + dx, y as i64 + dy);
            *cursor = gallop(column, *cursor, lo);
            for &e in column[*cursor..].iter().take_while(|&&e| e >> 32 <= hi) {
                out.insert(e as u32)?;
            }
        }
        Some(out)
    }
}

/// A small set of triangles.
struct Candidates {
    list: [u32; MAX_CANDIDATES],
    len: usize,
}

impl Candidates {
    /// Adds `j` unless it is there; `None` when the set is full.
    fn insert(&mut self, j: u32) -> Option<()> {
        if self.list[..self.len].contains(&j) {
            return Some(());
        }
        *self.list.get_mut(self.len)? = j;
        self.len += 1;
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cubes::SparseCubes;
    use crate::materials::Appearance;

    /// Grid resolution of the tests.
    const N: u32 = 32;

    /// An appearance whose surface has `triangles` (grid coordinates of a grid of `N`³ with
    /// the identity normalization), and that grid.
    fn grid_surface(triangles: &[[[f64; 3]; 3]]) -> (Appearance, SparseCubes) {
        let mut app = Appearance::default();
        for (k, t) in triangles.iter().enumerate() {
            for p in t {
                let unit = p.map(|g| (g / f64::from(N) - 0.5) as f32);
                app.surface.positions.push(unit);
            }
            let i = 3 * k as u32;
            app.surface.triangles.push([i, i + 1, i + 2]);
        }
        let cubes = SparseCubes {
            resolution: N,
            normalization: Default::default(),
            coords: Vec::new(),
            sdf: Vec::new(),
            deformation: Vec::new(),
            cells: Vec::new(),
        };
        (app, cubes)
    }

    /// A tilted sheet of two large triangles, a fold of two more, and a fan of small ones.
    fn triangles() -> Vec<[[f64; 3]; 3]> {
        let mut t = vec![
            [[2.3, 3.1, 4.2], [29.7, 5.3, 9.9], [3.4, 28.8, 7.1]],
            [[29.7, 5.3, 9.9], [28.1, 29.2, 12.6], [3.4, 28.8, 7.1]],
            [[6.5, 6.5, 20.5], [25.5, 6.5, 20.5], [16.0, 16.0, 27.5]],
            [[6.5, 6.5, 20.5], [16.0, 16.0, 27.5], [6.5, 25.5, 20.5]],
        ];
        for k in 0..24 {
            let a = f64::from(k) * std::f64::consts::TAU / 24.0;
            let b = a + std::f64::consts::TAU / 24.0;
            t.push([
                [16.2, 16.3, 15.1],
                [16.2 + 4.0 * a.cos(), 16.3 + 4.0 * a.sin(), 16.1],
                [16.2 + 4.0 * b.cos(), 16.3 + 4.0 * b.sin(), 16.1],
            ]);
        }
        t
    }

    /// The distance from `q` to the nearest of the surface's triangles, by trying them all.
    fn nearest_distance(surface: &GridSurface, q: [f64; 3]) -> f64 {
        surface
            .triangles
            .iter()
            .map(|&(t, _)| dist2(closest_point_on_triangle(q, &surface.corners(t)), q))
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }

    /// Crossings of the slices `xs` of `surface` (every triangle cut there).
    fn crossings_of(surface: &GridSurface, xs: (i64, i64)) -> Crossings {
        let mut c = Crossings::new(xs);
        for (j, &(t, _)) in surface.triangles.iter().enumerate() {
            clip::for_each_piece_in(surface.corners(t), xs, |cell, _, _| {
                c.record(cell, j as u32)
            });
        }
        c
    }

    /// Every cell of the grid whose centre is within 2 of the surface, in order, with that
    /// distance.
    fn band(surface: &GridSurface) -> Vec<([u16; 3], f64)> {
        let n = N as u16;
        let cells = (0..n).flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| [x, y, z])));
        cells
            .map(|c| (c, nearest_distance(surface, c.map(|v| f64::from(v) + 0.5))))
            .filter(|&(_, d)| d < 2.0)
            .collect()
    }

    #[test]
    fn answers_from_the_cells_around_are_the_whole_surfaces_nearest() {
        let (app, cubes) = grid_surface(&triangles());
        let surface = GridSurface::new(&app, &cubes);
        let mut crossings = crossings_of(&surface, (0, i64::from(N) - 1));
        crossings.sort();
        let mut walker = crossings.walker();
        let band = band(&surface);
        let mut answered = 0;
        for &(cell, want) in &band {
            if let Some(found) = walker.closest(cell, &surface) {
                let centre = cell.map(|v| f64::from(v) + 0.5);
                let got = dist2(found.point, centre).sqrt();
                assert!((got - want).abs() < 1e-12, "{cell:?}: {got} against {want}");
                assert!(want < REACH);
                answered += 1;
            } else {
                assert!(want >= REACH - 1e-3, "{cell:?} at {want} went unanswered");
            }
        }
        assert!(
            answered * 10 > band.len() * 6,
            "{answered} of {}",
            band.len()
        );
    }

    #[test]
    fn a_slice_at_the_end_of_the_covered_ones_answers_once_its_neighbour_is_covered() {
        let (app, cubes) = grid_surface(&triangles());
        let surface = GridSurface::new(&app, &cubes);
        let everything: Vec<u32> = (0..surface.triangles.len() as u32).collect();
        let slice: Vec<([u16; 3], f64)> = band(&surface)
            .into_iter()
            .filter(|(c, _)| c[0] == 12)
            .collect();
        let answered = |crossings: &mut Crossings| {
            crossings.sort();
            let mut walker = crossings.walker();
            let mut count = 0;
            for &(cell, want) in &slice {
                if let Some(found) = walker.closest(cell, &surface) {
                    let got = dist2(found.point, cell.map(|v| f64::from(v) + 0.5)).sqrt();
                    assert!((got - want).abs() < 1e-12, "{cell:?}: {got} against {want}");
                    count += 1;
                }
            }
            count
        };
        // A part of the one slice 12: only cells nearer than half a cell are certain.
        let mut alone = crossings_of(&surface, (12, 12));
        let few = answered(&mut alone);
        let mut covered = crossings_of(&surface, (12, 12));
        covered.cover(11, &surface, &everything);
        covered.cover(13, &surface, &everything);
        covered.cover(20, &surface, &everything); // not next to the covered slices: no effect
        let many = answered(&mut covered);
        assert!(few < many, "{few} then {many} of {}", slice.len());
        let within_reach = slice.iter().filter(|(_, d)| *d < REACH - 1e-3).count();
        assert_eq!(many, within_reach);
    }

    #[test]
    fn crossings_spread_over_too_many_columns_send_every_cell_to_the_whole_surface() {
        let (app, cubes) = grid_surface(&triangles());
        let surface = GridSurface::new(&app, &cubes);
        let mut sparse = crossings_of(&surface, (0, i64::from(N) - 1));
        let queries = sparse.hits.len();
        assert!(sparse.worth_sorting_for(queries));
        // The same crossings, said to cover every slice of the largest grid.
        sparse.xs = (-1, i64::from(u16::MAX) + 1);
        assert!(!sparse.worth_sorting_for(queries));
        sparse.sort();
        let mut walker = sparse.walker();
        assert!(band(&surface)
            .iter()
            .all(|&(cell, _)| walker.closest(cell, &surface).is_none()));
    }
}
