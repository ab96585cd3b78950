//! §13 (with `params.output_span`): the output's box framed instead of the source's, for a
//! consumer that reads the output mesh as filling its cube. TRELLIS.2's
//! `FlexiDualGridDataset.read_mesh` (`trellis2/datasets/flexi_dual_grid.py` of
//! microsoft/TRELLIS.2) centres every mesh dump's bounding box and scales its longest side to
//! 0.99999 of the grid, and its own `data_toolkit/dual_grid.py` computes the dual grid from the
//! mesh so placed: a grid that is to agree with the mesh as read must come from a mesh that is
//! already there. The source's box does not say where the output's is (a shell around an open
//! part reaches 0.9 voxel beyond it, marching cubes cuts tips short), so:
//!
//! 1. the source's box is fitted with [`FIRST_ROOM`] voxel of room at each end of the target;
//! 2. the output's box is measured and the conversion runs again with the normalization that
//!    maps it centred on the grid, its longest side ending in the middle of the cells where
//!    the target's ends lie ([`refit`]);
//! 3. the ends are put exactly on the target ([`snap`]): on each axis the crossings beyond it
//!    are moved back along their own grid edges, or the outermost one out along its edge, by
//!    changing φ at the edge's outer corner. A crossing that stays on its edge changes no
//!    sign, no crossed edge and no active cell: only where the surface meets that edge. The
//!    longest side ends on the target `span · N / 2` from the centre, every other axis
//!    symmetrically about the centre, so that re-centring and rescaling the output as
//!    `read_mesh` does moves nothing.
//!
//! Step 3 needs each end of the output within the cell where its target lies, and the two
//! ends of an axis in mirrored cells; when the second conversion misses that (the output's
//! box moved more than expected), it is refitted from its own box once more. A conversion
//! whose ends cannot be put there is returned as it is; the export that needs the frame
//! checks it and says so.

use crate::grid::cubes::SparseCubes;
use crate::grid::normalization::Normalization;
use crate::stages::extract::extract;

/// Conversions after the first, each refitted from the box of the one before.
pub(crate) const REFITS: usize = 3;

/// Room between an end of the source's box and the target in the first conversion, in voxels:
/// the shell around an open part reaches 0.9 voxel beyond it (`Params::shell_half_thickness`).
pub const FIRST_ROOM: f64 = 1.0;

/// The least distance, in voxels, between a moved crossing and either corner of its edge on
/// an axis whose target is free to choose.
const CLEARANCE: f64 = 1e-3;

/// The least distance, in voxels, between any moved crossing and a corner of its edge: well
/// above the `f32` rounding of a coordinate (6e-8 of the grid, 6e-5 voxel at 1024), well
/// below the 5e-6 of the grid TRELLIS.2's 0.99999 leaves (3e-4 voxel at 64).
const EDGE_MIN: f64 = 1e-4;

/// How far, in voxels, an end of the output may be from its target after [`snap`] (φ is
/// `f32`: the crossing lands within about 1e-6 voxel of it).
pub const SNAP_TOLERANCE: f64 = 1e-4;

/// A box: lowest and highest corner.
type Bounds = ([f64; 3], [f64; 3]);

/// The source's span of the first conversion: the target less [`FIRST_ROOM`] at each end, at
/// most what `margin_cells` leaves.
pub fn first_span(span: f64, resolution: u32, margin_cells: u32) -> f64 {
    let n = resolution as f64;
    let widest = (n - 2.0 * margin_cells as f64) / n;
    ((span * n - 2.0 * FIRST_ROOM) / n).min(widest)
}

/// How far inside the target the second conversion puts the ends of the output's longest
/// side, in voxels: [`snap`] then moves the outermost crossing out by about this much, and a
/// second conversion whose box lands up to this much farther out than asked still leaves
/// its ends on the target's side of the grid plane beyond it.
const AIM_INSIDE: f64 = 0.1;

/// Where the second conversion puts the ends of the output's longest side (grid
/// coordinates): [`AIM_INSIDE`] inside the target's ends `N/2 ± span·N/2`.
fn aim(resolution: u32, span: f64) -> (f64, f64) {
    let n = resolution as f64;
    let half = span * n / 2.0;
    (n / 2.0 - half + AIM_INSIDE, n / 2.0 + half - AIM_INSIDE)
}

/// The clearance from grid planes [`best_scale`] seeks for the other axes' ends, in voxels:
/// several times how far the second conversion's box moves from the one predicted.
const PLANE_CLEARANCE: f64 = 0.05;

/// The normalization that maps the `output` box of `cubes` (grid coordinates) centred on the
/// grid with its longest side between the middles of [`aim`]: the grid scaled by σ about the
/// output's centre, `g' = N/2 + σ·(g − o)`, which is the scale `σ·s` and the centre
/// `c − (N/2 − o)/(s·N)`. σ may shorten that length by up to 0.3 voxel or lengthen it by
/// 0.1 so that the other axes' ends stay off grid planes ([`best_scale`]); it is lowered where
/// the `source` box would come closer than `margin` cells to the border.
pub(crate) fn refit(
    cubes: &SparseCubes,
    output: Bounds,
    span: f64,
    source: Bounds,
    margin: u32,
) -> Normalization {
    let res = cubes.resolution;
    let n = res as f64;
    let (lo, hi) = output;
    let norm = cubes.normalization;
    let extents: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(1e-9));
    let (low_end, high_end) = aim(res, span);
    let sigma = best_scale(&extents, high_end - low_end, n);
    let centre = std::array::from_fn(|a| {
        norm.center[a] - (n / 2.0 - 0.5 * (lo[a] + hi[a])) / (norm.scale * n)
    });
    let fit = Normalization {
        center: centre,
        scale: sigma * norm.scale,
    };
    within_margin(fit, source, res, margin)
}

/// The scale σ that takes the longest of `extents` to `length` (or up to 0.3 voxel shorter,
/// 0.1 longer) and keeps the other axes' ends, centred, [`PLANE_CLEARANCE`] from grid planes
/// (an end at a plane could not be moved onto a target mirrored about the centre,
/// [`targets`]); the nearest to `length` that does, else the one that keeps them farthest.
fn best_scale(extents: &[f64; 3], length: f64, n: f64) -> f64 {
    let longest = extents.iter().copied().fold(0.0f64, f64::max);
    let clearance = |sigma: f64| {
        extents
            .iter()
            .filter(|&&e| e < longest)
            .map(|&e| plane_distance(n / 2.0 + sigma * e / 2.0).min(PLANE_CLEARANCE))
            .fold(PLANE_CLEARANCE, f64::min)
    };
    let mut best = (length / longest, clearance(length / longest));
    for k in 1..=16 {
        for step in [-0.3, 0.1] {
            let sigma = (length + step * k as f64 / 16.0) / longest;
            let c = clearance(sigma);
            if c > best.1 {
                best = (sigma, c);
            }
        }
    }
    best.0
}

/// Distance from `x` to the nearest integer.
fn plane_distance(x: f64) -> f64 {
    (x - x.round()).abs()
}

/// `fit`, scaled down about the grid's centre where it would bring the `source` box closer
/// than `margin` cells to the border.
fn within_margin(fit: Normalization, source: Bounds, res: u32, margin: u32) -> Normalization {
    let n = res as f64;
    let room = n / 2.0 - margin as f64;
    let (lo, hi) = (
        fit.source_to_grid(source.0, res),
        fit.source_to_grid(source.1, res),
    );
    let reach = (0..3)
        .map(|a| (n / 2.0 - lo[a]).max(hi[a] - n / 2.0))
        .fold(0.0f64, f64::max);
    if reach <= room {
        return fit;
    }
    Normalization {
        scale: fit.scale * room / reach,
        ..fit
    }
}

/// Puts the ends of the output of `cubes` exactly on the targets of `span` (module docs, step
/// 3), or says why it cannot; on failure `cubes` is left as it was.
pub fn snap(cubes: &mut SparseCubes, span: f64) -> std::result::Result<(), String> {
    let (lo, hi) = extract(cubes).bounds().ok_or("the output is empty")?;
    let goal = targets((lo, hi), cubes.resolution, span)?;
    let saved = cubes.sdf.clone();
    let moved = (0..3).try_for_each(|a| move_ends(cubes, a, goal[a]));
    let landed = moved.and_then(|()| {
        let (lo, hi) = extract(cubes).bounds().ok_or("the output is empty")?;
        let off = (0..3)
            .map(|a| (lo[a] - goal[a].0).abs().max((hi[a] - goal[a].1).abs()))
            .fold(0.0f64, f64::max);
        match off <= SNAP_TOLERANCE {
            true => Ok(()),
            false => Err(format!("the ends landed {off:.2e} voxel off their targets")),
        }
    });
    if landed.is_err() {
        cubes.sdf = saved;
    }
    landed
}

/// Per axis, where the output's ends go (grid coordinates): the longest axis's on
/// `N/2 ± span·N/2`, every other axis's symmetric about `N/2`, each within the cell its end
/// lies in now (so that it moves along its own edge) and [`CLEARANCE`] from the cell's planes.
pub fn targets(
    output: Bounds,
    resolution: u32,
    span: f64,
) -> std::result::Result<[(f64, f64); 3], String> {
    let n = resolution as f64;
    let (c, half) = (n / 2.0, span * n / 2.0);
    let (lo, hi) = output;
    let longest = (0..3).fold(0, |m, a| if hi[a] - lo[a] > hi[m] - lo[m] { a } else { m });
    let mut goal = [(0.0, 0.0); 3];
    for a in 0..3 {
        // The half-widths m whose ends c − m and c + m stay in the cells of lo and hi.
        // The longest axis's target is the consumer's (0.99999 of TRELLIS.2's grid ends
        // 5e-6 of it inside the border), so its clearance is only to keep off the planes.
        let clear = if a == longest { EDGE_MIN } else { CLEARANCE };
        let from = (c - lo[a].floor() - 1.0).max(hi[a].floor() - c) + clear;
        let to = (c - lo[a].floor()).min(hi[a].floor() + 1.0 - c) - clear;
        let upper = to.min(half);
        let m = match (a == longest, from <= upper) {
            (true, _) => half,
            (false, true) => (0.5 * (hi[a] - lo[a])).clamp(from, upper),
            (false, false) => upper,
        };
        if !(from <= m && m <= to) || m > half {
            return Err(format!(
                "axis {a}: the output's ends {:.4} and {:.4} cannot both reach a target \
                 symmetric about {c} within their cells (half-width {m:.4} not in \
                 [{from:.4}, {to:.4}])",
                lo[a], hi[a]
            ));
        }
        goal[a] = (c - m, c + m);
    }
    Ok(goal)
}

/// Moves the crossings of the edges along `axis` onto `goal`: those beyond either end back to
/// it, and when none is beyond, the outermost out to it; each by φ at its edge's outer corner.
fn move_ends(
    cubes: &mut SparseCubes,
    axis: usize,
    goal: (f64, f64),
) -> std::result::Result<(), String> {
    let crossings = axis_crossings(cubes, axis);
    for (end, target) in [(Side::Low, goal.0), (Side::High, goal.1)] {
        let beyond: Vec<&Crossing> = crossings
            .iter()
            .filter(|x| end.beyond(x.at, target))
            .collect();
        let outermost = crossings.iter().max_by(|p, q| end.order(p.at, q.at));
        let chosen = match (beyond.is_empty(), outermost) {
            (false, _) => beyond,
            (true, Some(x)) => vec![x],
            (true, None) => return Err(format!("axis {axis}: no crossing along it")),
        };
        for x in chosen {
            put(cubes, x, end, target)?;
        }
    }
    Ok(())
}

/// An end of an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    /// The lowest coordinates.
    Low,
    /// The highest.
    High,
}

impl Side {
    /// Whether `at` lies past `target` on this side.
    fn beyond(self, at: f64, target: f64) -> bool {
        match self {
            Side::Low => at < target,
            Side::High => at > target,
        }
    }

    /// Orders `p` before `q` when `q` is farther out on this side.
    fn order(self, p: f64, q: f64) -> std::cmp::Ordering {
        match self {
            Side::Low => q.total_cmp(&p),
            Side::High => p.total_cmp(&q),
        }
    }
}

/// A sign change of φ along a grid edge of one axis.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    /// Index in `coords` of the edge's lower corner.
    lower: usize,
    /// Index of its upper corner.
    upper: usize,
    /// The lower corner's coordinate along the axis.
    base: f64,
    /// Where the surface crosses the edge along the axis (as the extraction places it).
    at: f64,
}

/// Every edge along `axis` between stored vertices with a sign change (zero counts as
/// outside), with where marching cubes puts its crossing.
fn axis_crossings(cubes: &SparseCubes, axis: usize) -> Vec<Crossing> {
    let mut out = Vec::new();
    for (lower, &c) in cubes.coords.iter().enumerate() {
        let mut next = c;
        let Some(step) = c[axis].checked_add(1) else {
            continue;
        };
        next[axis] = step;
        let Some(upper) = cubes.vertex_index(next) else {
            continue;
        };
        let (sa, sb) = (cubes.sdf[lower] as f64, cubes.sdf[upper] as f64);
        if (sa < 0.0) == (sb < 0.0) {
            continue;
        }
        let w = sa / (sa - sb);
        let w = if w.is_finite() {
            w.clamp(0.0, 1.0)
        } else {
            0.5
        };
        let base = c[axis] as f64;
        out.push(Crossing {
            lower,
            upper,
            base,
            at: base + w,
        });
    }
    out
}

/// Moves crossing `x` to `target` along its edge by φ at its corner on `end`'s side, which
/// must be outside and the other corner inside.
fn put(
    cubes: &mut SparseCubes,
    x: &Crossing,
    end: Side,
    target: f64,
) -> std::result::Result<(), String> {
    let w = target - x.base;
    if !(EDGE_MIN * 0.5..=1.0 - EDGE_MIN * 0.5).contains(&w) {
        return Err(format!(
            "the crossing at {:.4} cannot reach {target:.4} along its edge",
            x.at
        ));
    }
    let (outer, inner, share) = match end {
        Side::High => (x.upper, x.lower, (1.0 - w) / w),
        Side::Low => (x.lower, x.upper, w / (1.0 - w)),
    };
    let inside = cubes.sdf[inner] as f64;
    if !(inside < 0.0 && cubes.sdf[outer] >= 0.0) {
        return Err(format!(
            "the crossing at {:.4} has its inside towards the end of the axis",
            x.at
        ));
    }
    // High: w = φl / (φl − φu), so φu = −φl·(1 − w)/w; low: φl = −φu·w/(1 − w).
    cubes.sdf[outer] = (-inside * share) as f32;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sphere's φ (signed distance in voxels) on every vertex of a grid of `n`.
    fn sphere(n: u16, centre: [f64; 3], radius: f64) -> SparseCubes {
        let mut coords = Vec::new();
        let mut sdf = Vec::new();
        for x in 0..=n {
            for y in 0..=n {
                for z in 0..=n {
                    let d = [x, y, z]
                        .iter()
                        .zip(centre)
                        .map(|(&v, c)| (v as f64 - c).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    coords.push([x, y, z]);
                    sdf.push((d - radius) as f32);
                }
            }
        }
        let cells = (0..n)
            .flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| [x, y, z])))
            .collect();
        SparseCubes {
            resolution: n as u32,
            normalization: Normalization::default(),
            deformation: vec![[0.0; 3]; coords.len()],
            coords,
            sdf,
            cells,
        }
    }

    /// The sign of every vertex, and the active cells, before and after.
    fn signs(c: &SparseCubes) -> Vec<bool> {
        c.sdf.iter().map(|&s| s < 0.0).collect()
    }

    #[test]
    fn the_ends_land_on_their_targets_without_changing_a_sign() {
        // Off-centre by 0.03 voxel, its ends in the cells of the targets of span 0.79.
        let mut cubes = sphere(24, [12.03, 11.98, 12.01], 9.2);
        let before = signs(&cubes);
        let span = 0.79;
        assert_eq!(snap(&mut cubes, span), Ok(()));
        assert_eq!(signs(&cubes), before);
        let (lo, hi) = extract(&cubes).bounds().unwrap_or_default();
        let half = span * 24.0 / 2.0;
        let widest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
        assert!(
            (widest - 2.0 * half).abs() < SNAP_TOLERANCE,
            "{lo:?} {hi:?}"
        );
        for a in 0..3 {
            assert!(
                (lo[a] + hi[a] - 24.0).abs() < 2.0 * SNAP_TOLERANCE,
                "{a}: {lo:?} {hi:?}"
            );
        }
    }

    #[test]
    fn an_end_in_another_cell_than_its_target_is_refused_and_nothing_changes() {
        // Radius 8.2: the ends lie a cell inside the targets of span 0.79.
        let mut cubes = sphere(24, [12.03, 11.98, 12.01], 8.2);
        let before = cubes.sdf.clone();
        let refused = snap(&mut cubes, 0.79);
        assert!(
            matches!(&refused, Err(m) if m.contains("cannot")),
            "{refused:?}"
        );
        assert_eq!(cubes.sdf, before);
    }

    #[test]
    fn the_scale_keeps_the_other_axes_ends_off_grid_planes() {
        // An axis whose centred ends would sit on planes (extent 10 about 12) gets a scale
        // that moves them off, within 0.3 voxel of the longest side's length.
        let sigma = best_scale(&[20.0, 10.0, 20.0], 20.0, 24.0);
        assert!((-0.3 - 1e-12..=0.1 + 1e-12).contains(&(sigma * 20.0 - 20.0)));
        assert!(plane_distance(12.0 + sigma * 5.0) > 0.05, "{sigma}");
        assert_eq!(best_scale(&[20.0, 9.0, 20.0], 20.0, 24.0), 1.0);
    }

    #[test]
    fn the_first_span_leaves_room_for_a_shell_within_the_margin() {
        assert!((first_span(0.9, 100, 3) - 0.88).abs() < 1e-12);
        assert!((first_span(0.99, 100, 3) - 0.94).abs() < 1e-12);
    }
}
