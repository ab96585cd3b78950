//! Hole filling (paper §3.4), for meshes decoded from a VAE: boundary half-edges → closed
//! loops → ear filling by smallest angle.
//!
//! A boundary half-edge is a triangle edge `a → b` whose edge `{a, b}` has no other triangle.
//! The filling runs along the reversed edges `b → a`, so every added triangle agrees with the
//! orientation of the surface around the hole. At each step the ear at the loop vertex `i`
//! with the smallest angle `A_i = atan2(|d₁ × d₂|, −d₁ · d₂)` is cut (`d₁`, `d₂` the loop's
//! edge vectors into and out of `i`). A vertex that turns against the hole's mean normal
//! (a reflex vertex of a non-convex hole) counts as `2π − A_i`, which on convex holes is the
//! paper's rule unchanged. A convex ear that contains another loop vertex (seen along the
//! hole's mean normal) is passed over while another ear is possible, so non-convex holes are
//! filled without folds. An ear whose closing edge already exists in the mesh is never cut
//! (it would make a non-manifold edge); a hole left with only such ears stays partly open.
//!
//! Vertex indices are used as they are: weld an unindexed mesh first
//! ([`crate::mesh::topology::weld`]).

use crate::mesh::TriMesh;
use crate::vec3::{cross, dot, sub};
use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;

/// What [`fill_holes`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct HoleStats {
    /// Boundary loops found.
    pub holes: u64,
    /// Loops closed completely.
    pub filled: u64,
    /// Loops left partly or wholly open (degenerate, or only ears that would duplicate an
    /// edge).
    pub unfilled: u64,
    /// Triangles added.
    pub triangles_added: u64,
    /// Edges in the longest loop.
    pub largest_hole: u64,
    /// Boundary half-edges that could not be chained into a closed loop.
    pub open_boundary_edges: u64,
}

/// The boundary loops of `mesh`, each as its vertices in filling order (the reverse of the
/// boundary half-edges), plus the number of boundary half-edges left unchained. Loops are
/// traced from the smallest vertex index; at a vertex with several boundary edges the one
/// to the smallest vertex is taken first.
pub fn boundary_loops(mesh: &TriMesh) -> (Vec<Vec<u32>>, u64) {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in valid_triangles(mesh) {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    // Filling edges b → a for each boundary half-edge a → b.
    let mut fill: Vec<(u32, u32)> = Vec::new();
    for t in valid_triangles(mesh) {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            if count.get(&(a.min(b), a.max(b))) == Some(&1) {
                fill.push((b, a));
            }
        }
    }
    fill.sort_unstable();
    let mut used = vec![false; fill.len()];
    let first_from = |v: u32| fill.partition_point(|e| e.0 < v);
    let mut loops = Vec::new();
    let mut open = 0u64;
    for s in 0..fill.len() {
        if used[s] {
            continue;
        }
        used[s] = true;
        let start = fill[s].0;
        let mut lp = vec![start];
        let mut edges = 1u64;
        let mut cur = fill[s].1;
        let closed = loop {
            if cur == start {
                break true;
            }
            lp.push(cur);
            let mut j = first_from(cur);
            while j < fill.len() && fill[j].0 == cur && used[j] {
                j += 1;
            }
            if j >= fill.len() || fill[j].0 != cur {
                break false;
            }
            used[j] = true;
            edges += 1;
            cur = fill[j].1;
        };
        if closed {
            loops.push(lp);
        } else {
            open += edges;
        }
    }
    (loops, open)
}

fn valid_triangles(mesh: &TriMesh) -> impl Iterator<Item = &[u32; 3]> {
    let n = mesh.positions.len();
    mesh.triangles.iter().filter(move |t| {
        t[0] != t[1] && t[1] != t[2] && t[0] != t[2] && t.iter().all(|&v| (v as usize) < n)
    })
}

/// Fills every boundary loop of `mesh` by ear cutting (see the module doc). Positions are
/// unchanged; triangles are appended.
pub fn fill_holes(mesh: &TriMesh) -> (TriMesh, HoleStats) {
    let mut out = mesh.clone();
    let mut stats = HoleStats::default();
    let (loops, open) = boundary_loops(mesh);
    stats.open_boundary_edges = open;
    stats.holes = loops.len() as u64;
    let mut edges: HashSet<(u32, u32)> = HashSet::new();
    for t in valid_triangles(mesh) {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    for lp in &loops {
        stats.largest_hole = stats.largest_hole.max(lp.len() as u64);
        let before = out.triangles.len();
        if fill_loop(&mut out, lp, &mut edges) {
            stats.filled += 1;
        } else {
            stats.unfilled += 1;
        }
        stats.triangles_added += (out.triangles.len() - before) as u64;
    }
    (out, stats)
}

/// Whether no other live loop vertex lies inside the ear (or on its closing edge) at `i` (in the hole's
/// plane).
fn ear_is_empty(
    flat: &[[f64; 2]],
    lp: &[u32],
    i: usize,
    prev: &[usize],
    next: &[usize],
    alive: &[bool],
) -> bool {
    let (a, b, c) = (flat[prev[i]], flat[i], flat[next[i]]);
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area <= 0.0 {
        return true;
    }
    let eps = 1e-12 * area;
    let ids = [lp[prev[i]], lp[i], lp[next[i]]];
    let mut j = next[next[i]];
    while j != prev[i] {
        if alive[j] && !ids.contains(&lp[j]) {
            let p = flat[j];
            let e = |u: [f64; 2], v: [f64; 2]| {
                (v[0] - u[0]) * (p[1] - u[1]) - (v[1] - u[1]) * (p[0] - u[0])
            };
            let corner = p == a || p == b || p == c;
            if !corner && e(a, b) >= -eps && e(b, c) >= -eps && e(c, a) >= -eps {
                return false;
            }
        }
        j = next[j];
    }
    true
}

/// The Newell normal of a closed loop of points: the hole's mean orientation (its length is
/// twice the loop's projected area; zero for a degenerate loop).
fn newell_normal(pts: &[[f64; 3]]) -> [f64; 3] {
    let k = pts.len();
    let mut normal = [0.0; 3];
    for i in 0..k {
        let (a, b) = (pts[i], pts[(i + 1) % k]);
        normal[0] += (a[1] - b[1]) * (a[2] + b[2]);
        normal[1] += (a[2] - b[2]) * (a[0] + b[0]);
        normal[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    normal
}

/// The points in 2-D coordinates of the plane normal to `normal` (empty when the normal is
/// zero: the loop has no plane).
fn project_to_plane(pts: &[[f64; 3]], normal: [f64; 3]) -> Vec<[f64; 2]> {
    let nn = dot(normal, normal).sqrt();
    if nn.is_nan() || nn <= 0.0 {
        return Vec::new();
    }
    let n = normal.map(|x| x / nn);
    let t = if n[0].abs() < 0.6 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross(n, t);
    let lu = dot(u, u).sqrt();
    let u = u.map(|x| x / lu);
    let v = cross(n, u);
    pts.iter().map(|&q| [dot(q, u), dot(q, v)]).collect()
}

/// Ear-fills one loop; returns whether it was closed completely.
fn fill_loop(mesh: &mut TriMesh, lp: &[u32], edges: &mut HashSet<(u32, u32)>) -> bool {
    let k = lp.len();
    if k < 3 {
        return false;
    }
    let p = |v: u32| mesh.positions[v as usize].map(f64::from);
    let pts: Vec<[f64; 3]> = lp.iter().map(|&v| p(v)).collect();
    let normal = newell_normal(&pts);
    let mut prev: Vec<usize> = (0..k).map(|i| (i + k - 1) % k).collect();
    let mut next: Vec<usize> = (0..k).map(|i| (i + 1) % k).collect();
    let mut alive = vec![true; k];
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let angle = |i: usize, prev: &[usize], next: &[usize], edges: &HashSet<(u32, u32)>| {
        let (a, b) = (lp[prev[i]], lp[next[i]]);
        if a == b || a == lp[i] || b == lp[i] || edges.contains(&key(a, b)) {
            return f64::INFINITY;
        }
        let d1 = sub(pts[i], pts[prev[i]]);
        let d2 = sub(pts[next[i]], pts[i]);
        let c = cross(d1, d2);
        let s = dot(c, c).sqrt();
        let mut ang = s.atan2(-dot(d1, d2));
        if dot(c, normal) < 0.0 {
            ang = 2.0 * PI - ang;
        }
        ang
    };
    let mut angles: Vec<f64> = (0..k).map(|i| angle(i, &prev, &next, edges)).collect();
    // The loop in its plane, for the "no other loop vertex inside the ear" test.
    let flat = project_to_plane(&pts, normal);
    let mut remaining = k;
    let mut blocked = vec![false; k];
    let mut tried = Vec::new();
    while remaining > 3 {
        for &j in &tried {
            blocked[j] = false;
        }
        tried.clear();
        let cut = loop {
            let best = (0..k)
                .filter(|&i| alive[i] && !blocked[i])
                .min_by(|&a, &b| angles[a].total_cmp(&angles[b]));
            match best.filter(|&i| angles[i].is_finite()) {
                None => break None,
                Some(i) if angles[i] >= PI || flat.is_empty() => break Some(i),
                Some(i) if ear_is_empty(&flat, lp, i, &prev, &next, &alive) => break Some(i),
                Some(i) => {
                    blocked[i] = true;
                    tried.push(i);
                }
            }
        };
        // With every convex ear blocked, fall back to the smallest angle.
        let cut = cut.or_else(|| {
            (0..k)
                .filter(|&i| alive[i] && angles[i].is_finite())
                .min_by(|&a, &b| angles[a].total_cmp(&angles[b]))
        });
        let Some(i) = cut else {
            return false;
        };
        let (a, b) = (prev[i], next[i]);
        mesh.triangles.push([lp[a], lp[i], lp[b]]);
        edges.insert(key(lp[a], lp[b]));
        alive[i] = false;
        next[a] = b;
        prev[b] = a;
        remaining -= 1;
        angles[a] = angle(a, &prev, &next, edges);
        angles[b] = angle(b, &prev, &next, edges);
    }
    let Some(i) = (0..k).find(|&i| alive[i]) else {
        return false;
    };
    let t = [lp[prev[i]], lp[i], lp[next[i]]];
    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return false;
    }
    mesh.triangles.push(t);
    true
}
