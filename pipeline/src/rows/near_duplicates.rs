//! Near-duplicate groups over shape signatures (`sparcubes::products::shape_signature`),
//! without comparing all pairs: leader clustering over a grid hash.
//!
//! Items are taken in item order. Each joins the nearest representative within the threshold
//! `T` (Euclidean distance of signatures; ties to the lower item index), or else becomes a
//! representative itself. So a group's representative is its lowest item index, every member
//! is within `T` of it (no chains of near pairs that drift from one shape to another), and
//! keeping the representatives and the items of no group drops only items with a kept
//! near-duplicate.
//!
//! Only representatives are searched, through a hash of grid cells of side `T` over the
//! signatures' first [`AXES`] principal components (of the item set, computed in item order
//! in double precision). A projection onto unit vectors never lengthens a difference, so any
//! representative within `T` lies in the item's cell or a neighbouring one: the `3^AXES`
//! cells are checked exactly. Everything runs in item order on one thread, so the groups are
//! the same on any machine.

// The matrix code indexes rows and columns by number, as the formulas do.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

/// Principal components the grid hash is over (`3^AXES` cells checked per item).
pub const AXES: usize = 4;

/// Items whose signatures are within the threshold of a representative's.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Position (in the input) of the representative: the group's first item.
    pub representative: usize,
    /// The other members' positions with their distance to the representative, in order.
    pub members: Vec<(usize, f64)>,
}

/// Every group of two or more items among `signatures` (in item order, all of one length),
/// at threshold `threshold`, ordered by representative.
pub fn groups(signatures: &[Vec<f32>], threshold: f64) -> Vec<Group> {
    let Some(dim) = signatures.first().map(Vec::len) else {
        return Vec::new();
    };
    let axes = principal_axes(signatures, dim, AXES.min(dim));
    // A zero threshold still needs cells of some size (only equal signatures group then).
    let cell = threshold.max(1e-9);
    let mut grid: HashMap<Vec<i64>, Vec<usize>> = HashMap::new();
    let mut leader_of: Vec<Option<(usize, f64)>> = vec![None; signatures.len()];
    let mut neighbours = Vec::new();
    for (i, s) in signatures.iter().enumerate() {
        let key: Vec<i64> = axes
            .iter()
            .map(|a| (project(s, a) / cell).floor() as i64)
            .collect();
        neighbour_keys(&key, &mut neighbours);
        let mut best: Option<(usize, f64)> = None;
        for k in &neighbours {
            for &r in grid.get(k).into_iter().flatten() {
                let d = sparcubes::products::shape_signature::distance(s, &signatures[r]);
                if d <= threshold && best.is_none_or(|(b, bd)| (d, r) < (bd, b)) {
                    best = Some((r, d));
                }
            }
        }
        match best {
            Some(found) => leader_of[i] = Some(found),
            None => grid.entry(key).or_default().push(i),
        }
    }
    collect_groups(&leader_of)
}

/// The groups from each item's representative and distance (`None`: a representative).
fn collect_groups(leader_of: &[Option<(usize, f64)>]) -> Vec<Group> {
    let mut by_leader: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    for (i, l) in leader_of.iter().enumerate() {
        if let Some((r, d)) = l {
            by_leader.entry(*r).or_default().push((i, *d));
        }
    }
    let mut groups: Vec<Group> = by_leader
        .into_iter()
        .map(|(representative, members)| Group {
            representative,
            members,
        })
        .collect();
    groups.sort_by_key(|g| g.representative);
    groups
}

fn project(s: &[f32], axis: &[f64]) -> f64 {
    s.iter().zip(axis).map(|(x, a)| f64::from(*x) * a).sum()
}

/// The keys of `key`'s cell and of every cell next to it (`3^len` in all) into `out`.
fn neighbour_keys(key: &[i64], out: &mut Vec<Vec<i64>>) {
    out.clear();
    out.push(key.to_vec());
    for a in 0..key.len() {
        let so_far = out.len();
        for k in 0..so_far {
            for step in [-1, 1] {
                let mut n = out[k].clone();
                n[a] = n[a].saturating_add(step);
                out.push(n);
            }
        }
    }
}

/// The `k` unit eigenvectors of the signatures' covariance with the largest eigenvalues
/// (sums in item order, so the same on any machine).
fn principal_axes(signatures: &[Vec<f32>], dim: usize, k: usize) -> Vec<Vec<f64>> {
    let n = signatures.len() as f64;
    let mut mean = vec![0.0; dim];
    for s in signatures {
        for (m, x) in mean.iter_mut().zip(s) {
            *m += f64::from(*x) / n;
        }
    }
    let mut cov = vec![vec![0.0; dim]; dim];
    let mut centred = vec![0.0; dim];
    for s in signatures {
        for (c, (x, m)) in centred.iter_mut().zip(s.iter().zip(&mean)) {
            *c = f64::from(*x) - m;
        }
        for a in 0..dim {
            for b in a..dim {
                cov[a][b] += centred[a] * centred[b];
            }
        }
    }
    for a in 0..dim {
        for b in 0..a {
            cov[a][b] = cov[b][a];
        }
    }
    let (values, vectors) = jacobi_eigen(cov);
    let mut order: Vec<usize> = (0..dim).collect();
    order.sort_by(|&a, &b| values[b].total_cmp(&values[a]).then(a.cmp(&b)));
    order[..k]
        .iter()
        .map(|&j| (0..dim).map(|i| vectors[i][j]).collect())
        .collect()
}

/// Eigenvalues and eigenvectors (as columns) of a symmetric matrix by cyclic Jacobi rotations
/// (Golub and Van Loan, "Matrix Computations", 4th ed., §8.5.2), sweeps until the
/// off-diagonal part is negligible.
fn jacobi_eigen(mut a: Vec<Vec<f64>>) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = a.len();
    let mut v: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    for _sweep in 0..64 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let scale: f64 = (0..n).map(|i| a[i][i] * a[i][i]).sum();
        if off <= 1e-24 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                rotate(&mut a, &mut v, p, q);
            }
        }
    }
    ((0..n).map(|i| a[i][i]).collect(), v)
}

/// One Jacobi rotation zeroing `a[p][q]`, applied to `a` and accumulated in `v`.
fn rotate(a: &mut [Vec<f64>], v: &mut [Vec<f64>], p: usize, q: usize) {
    if a[p][q] == 0.0 {
        return;
    }
    let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
    let t = if theta == 0.0 { 1.0 } else { t };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    let n = a.len();
    for k in 0..n {
        let (akp, akq) = (a[k][p], a[k][q]);
        a[k][p] = c * akp - s * akq;
        a[k][q] = s * akp + c * akq;
    }
    for k in 0..n {
        let (apk, aqk) = (a[p][k], a[q][k]);
        a[p][k] = c * apk - s * aqk;
        a[q][k] = s * apk + c * aqk;
    }
    for k in 0..n {
        let (vkp, vkq) = (v[k][p], v[k][q]);
        v[k][p] = c * vkp - s * vkq;
        v[k][q] = s * vkp + c * vkq;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The groups by brute force: the same leader rule over every pair.
    fn brute_force(signatures: &[Vec<f32>], threshold: f64) -> Vec<Group> {
        let dist = sparcubes::products::shape_signature::distance;
        let mut leaders: Vec<usize> = Vec::new();
        let mut leader_of = vec![None; signatures.len()];
        for (i, s) in signatures.iter().enumerate() {
            let best = leaders
                .iter()
                .map(|&r| (dist(s, &signatures[r]), r))
                .filter(|(d, _)| *d <= threshold)
                .min_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
            match best {
                Some((d, r)) => leader_of[i] = Some((r, d)),
                None => leaders.push(i),
            }
        }
        collect_groups(&leader_of)
    }

    /// `n` signatures of 8 entries from a fixed generator: clusters of one to four copies
    /// of a base point, each copy moved by up to `spread` along every entry.
    fn synthetic(n: usize, spread: f32) -> Vec<Vec<f32>> {
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut out = Vec::new();
        while out.len() < n {
            let base: Vec<f32> = (0..8).map(|_| next()).collect();
            let copies = 1 + (next() * 4.0) as usize;
            for _ in 0..copies.min(n - out.len()) {
                out.push(base.iter().map(|x| x + (next() - 0.5) * spread).collect());
            }
        }
        out
    }

    #[test]
    fn the_grid_finds_what_every_pair_finds() {
        let signatures = synthetic(3000, 0.03);
        for threshold in [0.02, 0.05, 0.2] {
            let fast = groups(&signatures, threshold);
            assert_eq!(fast, brute_force(&signatures, threshold), "at {threshold}");
            assert!(!fast.is_empty());
            for g in &fast {
                assert!(g
                    .members
                    .iter()
                    .all(|&(m, d)| m > g.representative && d <= threshold));
            }
        }
    }

    #[test]
    fn members_join_their_nearest_representative() {
        let s = |x: f32| vec![x, 0.0, 0.0];
        // 0 and 2 are representatives 1.0 apart; 3 is within 0.6 of both, nearer 2.
        let signatures = [s(0.0), s(0.1), s(1.0), s(0.55), s(5.0)];
        let g = groups(&signatures, 0.6);
        assert_eq!(
            g,
            [
                Group {
                    representative: 0,
                    members: vec![(1, 0.10000000149011612)]
                },
                Group {
                    representative: 2,
                    members: vec![(3, 0.44999998807907104)]
                },
            ]
        );
    }

    #[test]
    fn jacobi_finds_the_eigenvalues_of_a_known_matrix() {
        let (values, vectors) = jacobi_eigen(vec![
            vec![2.0, 1.0, 0.0],
            vec![1.0, 2.0, 0.0],
            vec![0.0, 0.0, 5.0],
        ]);
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        for (got, want) in sorted.iter().zip([1.0, 3.0, 5.0]) {
            assert!((got - want).abs() < 1e-12, "{values:?}");
        }
        let j = values
            .iter()
            .position(|v| (v - 3.0).abs() < 1e-9)
            .unwrap_or(0);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!(
            (vectors[0][j].abs() - h).abs() < 1e-9 && (vectors[1][j] - vectors[0][j]).abs() < 1e-9
        );
    }
}
