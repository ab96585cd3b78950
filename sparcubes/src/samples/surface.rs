//! Area-uniform points on a mesh: a cumulative area table over the triangles of positive
//! area, searched with one uniform number, and a uniform point inside the chosen triangle.

use super::rng::Draw;
use crate::mesh::TriMesh;
use crate::vec3::{norm, scale};

/// Cumulative areas of the triangles of positive area, in triangle order.
#[derive(Debug, Clone)]
pub struct AreaTable {
    /// Running sum of the areas (summed in triangle order, so it is reproducible).
    cumulative: Vec<f64>,
    /// The triangle of each entry.
    triangles: Vec<u32>,
    /// A guide to the search: entry `j` is where a search for `bucket(j)` (the `j`-th of
    /// `guide.len()` equal parts of the total) ends, so a draw only searches between the
    /// guides of its bucket and the next (the same answer as a search of the whole table).
    guide: Vec<u32>,
}

impl AreaTable {
    /// The table of `mesh`.
    pub fn new(mesh: &TriMesh) -> Self {
        let mut cumulative = Vec::with_capacity(mesh.triangles.len());
        let mut triangles = Vec::with_capacity(mesh.triangles.len());
        let mut total = 0.0;
        for t in 0..mesh.triangles.len() {
            let a = 0.5 * norm(mesh.face_normal(t));
            if a > 0.0 && a.is_finite() {
                total += a;
                cumulative.push(total);
                triangles.push(t as u32);
            }
        }
        let buckets = cumulative.len();
        let mut guide = Vec::with_capacity(buckets);
        let mut i = 0;
        for j in 0..buckets {
            let start = bucket(j, buckets, total);
            while i < buckets && cumulative[i] <= start {
                i += 1;
            }
            guide.push(i as u32);
        }
        Self {
            cumulative,
            triangles,
            guide,
        }
    }

    /// Whether the mesh has no triangle of positive area.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A point uniform by area and the unit normal of its triangle, from numbers
    /// `k..k + 3` of `d`.
    pub fn draw(&self, mesh: &TriMesh, d: &Draw, k: u64) -> ([f64; 3], [f64; 3]) {
        let total = self.cumulative.last().copied().unwrap_or(0.0);
        let target = d.uniform(k) * total;
        let t = self.triangles[self.entry(target)] as usize;
        let [a, b, c] = mesh.triangle(t);
        let r = d.uniform(k + 1).sqrt();
        let s = d.uniform(k + 2);
        let (wa, wb, wc) = (1.0 - r, r * (1.0 - s), r * s);
        let p = std::array::from_fn(|x| wa * a[x] + wb * b[x] + wc * c[x]);
        let n = mesh.face_normal(t);
        (p, scale(n, 1.0 / norm(n)))
    }

    /// The entry whose cumulative area is the first above `target` (the last entry for a
    /// target at or above the total).
    fn entry(&self, target: f64) -> usize {
        let total = self.cumulative.last().copied().unwrap_or(0.0);
        // The last bucket whose start is not above the target (its guide is not beyond the
        // answer; the next bucket's guide, if any, is not before it).
        let k_len = self.guide.len();
        let mut j = ((target / total * k_len as f64) as usize).min(k_len - 1);
        while j > 0 && bucket(j, k_len, total) > target {
            j -= 1;
        }
        while j + 1 < k_len && bucket(j + 1, k_len, total) <= target {
            j += 1;
        }
        let lo = self.guide[j] as usize;
        let hi = self
            .guide
            .get(j + 1)
            .map_or(self.cumulative.len(), |&g| g as usize);
        (lo + self.cumulative[lo..hi].partition_point(|&c| c <= target))
            .min(self.triangles.len() - 1)
    }
}

/// The start of bucket `j` of `buckets` equal parts of `total`.
#[inline]
fn bucket(j: usize, buckets: usize, total: f64) -> f64 {
    j as f64 * total / buckets as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::rng::uniforms;
    use crate::shapes::{merge, quad, sphere};

    #[test]
    fn guided_search_finds_the_entry_of_a_whole_table_search() {
        // Triangles of very different areas, so buckets hold from none to many entries.
        let mesh = merge(&[sphere([0.0; 3], 0.5, 30), quad(-0.9, -0.9, 0.2, 0.4, 0.55)]);
        let table = AreaTable::new(&mesh);
        let total = *table.cumulative.last().unwrap_or(&0.0);
        let whole = |t: f64| {
            table
                .cumulative
                .partition_point(|&c| c <= t)
                .min(table.triangles.len() - 1)
        };
        let k = table.guide.len();
        let targets = (0..20_000)
            .map(|i| uniforms(5, 1, i)[0] * total)
            .chain((0..k).map(|j| bucket(j, k, total)))
            .chain(table.cumulative.iter().copied())
            .chain([0.0, total]);
        for t in targets {
            assert_eq!(table.entry(t), whole(t), "target {t}");
        }
    }
}
