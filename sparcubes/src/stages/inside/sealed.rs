//! Vertices sealed in by triangles on every side: grouped, decided by the winding number, and
//! joined into thin closed parts that keep their surface where the grid can hold them
//! ([`decide_sealed`]).

use super::gaps::{parts_with_gaps, Sealed, NOT_SEALED};
use super::vote::{median_winding, verdict, Verdict, SAMPLES};
use crate::queries::winding::LazyWindingTree;
use crate::stages::band::Band;
use crate::stages::vertex_side::{open_neighbours, Side};
use crate::stages::voxelize::Voxelization;
use crate::union_find::components;
use rayon::prelude::*;

/// What [`decide_sealed`] found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SealedCounts {
    /// Groups of sealed vertices (joined through grid edges no triangle crosses).
    pub groups: u64,
    /// Groups whose winding number was ambiguous (left outside).
    pub ambiguous: u64,
    /// Groups inside two closed surfaces or more (|w| ≥ [`OVERLAP_FROM`]) and joined to no
    /// thin part: where closed parts overlap, left outside.
    pub overlaps: u64,
    /// Thin closed parts kept at their thickness: sealed vertices found inside, joined with
    /// their 26 neighbours.
    pub thin_parts: u64,
    /// Thin closed parts left to the thin shell because the grid cannot hold them: somewhere
    /// a grid edge crosses them with both ends outside, or none of their vertices lies
    /// [`THIN_PART_DEPTH`] deep.
    pub shelled_parts: u64,
    /// Sealed vertices joined through their 26 neighbours of which none lies
    /// [`THIN_PART_DEPTH`] deep: left to the thin shell without asking the winding number
    /// (whatever it says, such a part would be shelled), so not counted in `thin_parts` or
    /// `shelled_parts`.
    pub shallow: u64,
}

/// Decides the vertices that are still `Unknown` after [`crate::stages::sign::vertex_sides`]: those
/// sealed in by triangles on every side, with no surface-free cell to take a side from — the
/// inside of a closed part thinner than about two cells, or a pocket between sheets. They are
/// grouped through grid edges no triangle crosses (a group has one side), and each group is
/// inside if the winding number at its [`SAMPLES`] vertices farthest from the surface (median)
/// says solid; otherwise outside, as the grid alone would have it (air or ambiguous). A group
/// inside two closed surfaces or more ([`OVERLAP_FROM`]) is where closed parts overlap, not a
/// thin part: outside too, unless joined to a thin part ([`without_lone_overlaps`]).
///
/// A part found inside keeps its own surface (φ = ±UDF) only where the grid can hold it: a
/// part thinner than a cell has places no grid vertex falls into, where a grid edge crosses
/// it with both ends outside, and the exact field would leave a hole there. So the found
/// vertices are joined into parts (26 neighbours), and a part with such an edge next to one of
/// its vertices goes back to outside: it becomes a thin shell, as without the test. A part at
/// least a cell thick has a vertex in every grid edge's span across it, so it keeps its
/// surface.
pub fn decide_sealed(
    band: &Band,
    vox: &Voxelization,
    side: &mut [Side],
    tree: &LazyWindingTree,
    n: u32,
) -> SealedCounts {
    let Some(sealed) = SealedVertices::of(band, side) else {
        return SealedCounts::default();
    };
    let (position, coords) = (&sealed.position[..], &sealed.coords[..]);
    let (group_of, members, starts) = sealed_groups(band, vox, position, coords);
    let groups = starts.len() - 1;
    let first = |g: usize| members[starts[g] as usize] as usize;
    // The sealed vertices joined through their 26 neighbours: every thin part found below is
    // within one of these, so where none of its vertices lies THIN_PART_DEPTH deep, each
    // part in it would go back to the shell (below) whatever the winding number says, and
    // its groups are not asked (on the dev corpus most sealed groups are such rims, and
    // their queries, next to the surface, were most of the inside test's time on some).
    let (reach_of, reaches) = thin_parts(band, position, coords, &vec![true; coords.len()]);
    let reach_depth = deepest_per_label(band, &sealed.unknown, &reach_of, reaches, |_| true);
    let shallow = |g: usize| reach_depth[reach_of[first(g)] as usize] < THIN_PART_DEPTH;
    let asked: Vec<usize> = (0..groups).filter(|&g| !shallow(g)).collect();
    let (verdicts, overlap) = vote_groups(band, &sealed, (&members, &starts), &asked, tree);
    let solid: Vec<bool> = group_of
        .iter()
        .map(|&g| verdicts[g as usize] == Verdict::Solid)
        .collect();
    let found = without_lone_overlaps(band, position, coords, &solid, |q| {
        overlap[group_of[q] as usize]
    });
    // Where every deep enough set was found inside whole (the common case), its parts are
    // those sets: no second pass over the neighbours.
    let whole = (0..coords.len())
        .all(|q| found[q] == (reach_depth[reach_of[q] as usize] >= THIN_PART_DEPTH));
    let (part_of, parts) = if whole {
        renumbered(&reach_of, reaches, &found)
    } else {
        thin_parts(band, position, coords, &found)
    };
    let found_parts = Sealed {
        position,
        coords,
        found: &found,
        part_of: &part_of,
    };
    let too_thin = too_thin(band, vox, side, &sealed.unknown, &found_parts, parts, n);
    for (q, &id) in sealed.unknown.iter().enumerate() {
        side[id as usize] = if found[q] && !too_thin[part_of[q] as usize] {
            Side::Inside
        } else {
            Side::Outside
        };
    }
    let shelled = too_thin.iter().filter(|&&t| t).count() as u64;
    let shallow_reaches = reach_depth.iter().filter(|&&d| d < THIN_PART_DEPTH).count() as u64;
    SealedCounts {
        groups: groups as u64,
        ambiguous: asked
            .iter()
            .filter(|&&g| verdicts[g] == Verdict::Ambiguous)
            .count() as u64,
        overlaps: (0..groups)
            .filter(|&g| overlap[g] && !found[first(g)])
            .count() as u64,
        shallow: shallow_reaches,
        thin_parts: parts as u64 - shelled,
        shelled_parts: shelled,
    }
}

/// The band vertices still `Unknown`: their numbers, per band vertex its position among them
/// ([`NOT_SEALED`] if none) for O(1) look-ups, and their coordinates; `None` if there is none.
struct SealedVertices {
    /// Band vertex numbers, ascending.
    unknown: Vec<u32>,
    /// Per band vertex, its position in `unknown`, or [`NOT_SEALED`].
    position: Vec<u32>,
    /// Per position, the vertex's coordinates.
    coords: Vec<[u32; 3]>,
}

impl SealedVertices {
    /// The vertices of `band` whose `side` is still `Unknown`.
    fn of(band: &Band, side: &[Side]) -> Option<Self> {
        let unknown: Vec<u32> = (0..side.len() as u32)
            .into_par_iter()
            .filter(|&i| side[i as usize] == Side::Unknown)
            .collect();
        if unknown.is_empty() {
            return None;
        }
        let mut position = vec![NOT_SEALED; side.len()];
        for (q, &id) in unknown.iter().enumerate() {
            position[id as usize] = q as u32;
        }
        let coords = band.verts.coords_of(&unknown);
        Some(Self {
            unknown,
            position,
            coords,
        })
    }
}

/// The winding vote of each `asked` group (`groups`: members and CSR starts, positions in
/// `sealed`) at its [`SAMPLES`] vertices farthest from the surface (ties by vertex number):
/// per group its verdict (`Ambiguous` for a group not asked) and whether it is inside two
/// closed surfaces or more ([`OVERLAP_FROM`]).
fn vote_groups(
    band: &Band,
    sealed: &SealedVertices,
    (members, starts): (&[u32], &[u32]),
    asked: &[usize],
    tree: &LazyWindingTree,
) -> (Vec<Verdict>, Vec<bool>) {
    let groups = starts.len() - 1;
    let mut verdicts = vec![Verdict::Ambiguous; groups];
    let mut overlap = vec![false; groups];
    if asked.is_empty() {
        return (verdicts, overlap);
    }
    let tree = tree.get();
    let found: Vec<f64> = asked
        .par_iter()
        .map_init(
            || Vec::with_capacity(64),
            |stack, &g| {
                let mut group: Vec<u32> =
                    members[starts[g] as usize..starts[g + 1] as usize].to_vec();
                // Farthest from the surface first; ties by vertex number.
                let udf = |q: u32| band.nearest[sealed.unknown[q as usize] as usize].udf;
                group.sort_by(|&a, &b| udf(b).total_cmp(&udf(a)).then(a.cmp(&b)));
                let points: Vec<[f64; 3]> = group
                    .iter()
                    .take(SAMPLES)
                    .map(|&q| sealed.coords[q as usize].map(|v| v as f64))
                    .collect();
                median_winding(tree, &points, stack)
            },
        )
        .collect();
    for (&g, w) in asked.iter().zip(found) {
        verdicts[g] = verdict(w);
        overlap[g] = w >= OVERLAP_FROM;
    }
    (verdicts, overlap)
}

/// Per thin part of `found` (of `parts`), whether the grid cannot hold it: a grid edge
/// crosses it with both ends outside ([`parts_with_gaps`]), or none of its found vertices
/// (`unknown`, band vertex numbers) lies [`THIN_PART_DEPTH`] below the surface, so the grid
/// holds it in too few places. Such a part is a thin shell.
fn too_thin(
    band: &Band,
    vox: &Voxelization,
    side: &[Side],
    unknown: &[u32],
    found: &Sealed,
    parts: usize,
    n: u32,
) -> Vec<bool> {
    let mut too_thin = parts_with_gaps(band, vox, side, found, parts, n);
    let deepest = deepest_per_label(band, unknown, found.part_of, parts, |q| found.found[q]);
    for (t, &d) in too_thin.iter_mut().zip(&deepest) {
        *t |= d < THIN_PART_DEPTH;
    }
    too_thin
}

/// Per label (of `count`), the largest distance to the surface of the sealed vertices
/// (`unknown`, band vertex numbers) with that label for which `counted` holds; 0 for a label
/// without any.
fn deepest_per_label(
    band: &Band,
    unknown: &[u32],
    label: &[u32],
    count: usize,
    counted: impl Fn(usize) -> bool,
) -> Vec<f32> {
    let mut deepest = vec![0f32; count];
    for (q, &id) in unknown.iter().enumerate() {
        if counted(q) {
            let l = label[q] as usize;
            deepest[l] = deepest[l].max(band.nearest[id as usize].udf);
        }
    }
    deepest
}

/// Depth, in voxels, that at least one found vertex of a thin closed part must lie below its
/// surface for the part to keep that surface: a part whose vertices are all shallower (at
/// most about 0.6 voxel thick where the grid sees it) is held by the grid in too few places,
/// and its exact field loses the rest (tapering rims, curved walls), which cost F1 on the dev
/// corpus at 256³ against the thin shell (`yogurtBottle.obj` 99.7 → 98.6, `park-trashcan.obj`
/// 65.6 → 65.2, `left_finger.STL` 95.8 → 95.1). Plates of 1.2 voxels and more have vertices
/// about 0.6 deep and keep their surface (tests/convert_enclosed.rs).
pub const THIN_PART_DEPTH: f32 = 0.3;

/// |w| at or above which a sealed group is inside two closed surfaces or more: halfway
/// between one surface and two, as [`NESTED_STEP`] is half a surface's step.
///
/// Such a group is where closed parts overlap by less than the grid resolves (a screw in a
/// hole narrower than its shaft), not a thin part of its own. Inside, it would leave both
/// parts' surfaces with inside on each side, as sheets inside the solid, and each would
/// become a thin cavity 0.9 voxel off its place (§7 of docs/ALGORITHM.md); outside, as the
/// grid alone has it, the sliver is a thin gap whose walls are the parts' exact surfaces.
/// Overlap regions the flood encloses keep the parts' surfaces too (the nested rule).
pub const OVERLAP_FROM: f64 = 1.5;

/// Groups of the sealed vertices (positions in `unknown`, `position` per band vertex) through
/// grid edges no triangle crosses: each position's group (numbered by smallest position), and
/// the groups' members as CSR (members, starts). The neighbour look-ups run in parallel.
fn sealed_groups(
    band: &Band,
    vox: &Voxelization,
    position: &[u32],
    coords: &[[u32; 3]],
) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let pairs: Vec<(u32, u32)> = (0..coords.len())
        .into_par_iter()
        .flat_map_iter(|q| {
            open_neighbours(band, vox, coords[q]).filter_map(move |(j, _)| {
                let r = position[j as usize];
                (r != NOT_SEALED && r != q as u32).then_some((q as u32, r))
            })
        })
        .collect();
    let (group_of, groups) = components(coords.len(), &pairs, |_| true);
    let mut starts = vec![0u32; groups + 1];
    for &g in &group_of {
        starts[g as usize + 1] += 1;
    }
    for g in 0..groups {
        starts[g + 1] += starts[g];
    }
    let mut fill = starts.clone();
    let mut members = vec![0u32; coords.len()];
    for (q, &g) in group_of.iter().enumerate() {
        members[fill[g as usize] as usize] = q as u32;
        fill[g as usize] += 1;
    }
    (group_of, members, starts)
}

/// The 26 neighbour offsets that come after (0, 0, 0) in (x, y, z) order: each neighbouring
/// pair is visited once.
fn forward_neighbours() -> impl Iterator<Item = [i64; 3]> {
    (0..27i64)
        .map(|d| [d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1])
        .filter(|off| *off > [0, 0, 0])
}

/// Connected components, through the 26 neighbours, of the `found` sealed vertices: each
/// found position's part (numbered by smallest position), and the number of parts.
fn thin_parts(
    band: &Band,
    position: &[u32],
    coords: &[[u32; 3]],
    found: &[bool],
) -> (Vec<u32>, usize) {
    let pairs: Vec<(u32, u32)> = (0..coords.len())
        .into_par_iter()
        .filter(|&q| found[q])
        .flat_map_iter(|q| {
            let c = coords[q].map(|v| v as i64);
            forward_neighbours().filter_map(move |off| {
                let j = band
                    .verts
                    .id([c[0] + off[0], c[1] + off[1], c[2] + off[2]])?;
                let r = position[j as usize];
                (r != NOT_SEALED && found[r as usize]).then_some((q as u32, r))
            })
        })
        .collect();
    components(coords.len(), &pairs, |q| found[q])
}

/// The `solid` sealed vertices less those of overlaps ([`OVERLAP_FROM`]) that are not joined,
/// through their 26 neighbours, to a solid vertex that is no overlap.
///
/// A group inside two closed surfaces or more is where closed parts overlap (or one lies
/// inside another), not a thin part of its own: outside, as the grid alone has it — unless it
/// is joined to a thin part found inside (thin parts that cross or lap over each other, the
/// boards of a hut): there the sliver is the thin part's own inside as the grid sees it, and
/// outside it would cut the part through (the gap check would then shell all of it).
fn without_lone_overlaps(
    band: &Band,
    position: &[u32],
    coords: &[[u32; 3]],
    solid: &[bool],
    overlap: impl Fn(usize) -> bool,
) -> Vec<bool> {
    if !(0..coords.len()).any(|q| solid[q] && overlap(q)) {
        return solid.to_vec();
    }
    let (part_of, parts) = thin_parts(band, position, coords, solid);
    let mut thin = vec![false; parts];
    for q in 0..coords.len() {
        if solid[q] && !overlap(q) {
            thin[part_of[q] as usize] = true;
        }
    }
    (0..coords.len())
        .map(|q| solid[q] && (!overlap(q) || thin[part_of[q] as usize]))
        .collect()
}

/// `label` (of `count` labels) kept where `keep` holds, numbered again in the order of
/// their first kept item (as [`components`] numbers them); `u32::MAX` elsewhere.
fn renumbered(label: &[u32], count: usize, keep: &[bool]) -> (Vec<u32>, usize) {
    let mut new = vec![u32::MAX; count];
    let mut next = 0u32;
    let out = label
        .iter()
        .zip(keep)
        .map(|(&l, &k)| {
            if !k {
                return u32::MAX;
            }
            if new[l as usize] == u32::MAX {
                new[l as usize] = next;
                next += 1;
            }
            new[l as usize]
        })
        .collect();
    (out, next as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_components_renumbered_match_components_of_the_kept_items() {
        // Items 0..8 in components {0, 3, 5}, {1, 4}, {2, 7}, {6}; keep {1, 4} and {6}.
        let pairs = [(3, 0), (5, 3), (4, 1), (7, 2)];
        let (label, count) = components(8, &pairs, |_| true);
        assert_eq!(count, 4);
        let keep: Vec<bool> = (0..8).map(|q| [1, 4, 6].contains(&q)).collect();
        let direct = components(8, &pairs, |q| keep[q]);
        assert_eq!(renumbered(&label, count, &keep), direct);
        assert_eq!(direct.1, 2);
    }
}
