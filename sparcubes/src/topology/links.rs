//! The links of every vertex at once, for any mesh: the general path of [`super::check`]
//! where the triangles do not come in an order that [`super::tiles`] can follow.
//!
//! A pass over the triangles counts each vertex's triangles (atomics), a prefix sum gives
//! each vertex its rows, a second pass fills them, and a pass over the vertices reads them.
//! This holds every link in memory at once (8 bytes per triangle corner).

use super::fan::{LinkCounts, Scratch};
use super::CHUNK;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// The edge and vertex defects of the triangles of `triangles` that pass `keep` (in range,
/// not degenerate), over `nv` vertices.
pub(super) fn link_counts(
    triangles: &[[u32; 3]],
    nv: usize,
    keep: impl Fn(&[u32; 3]) -> bool + Sync,
) -> LinkCounts {
    let degree: Vec<AtomicU32> = (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|_| AtomicU32::new(0))
        .collect();
    triangles.par_chunks(CHUNK).for_each(|tris| {
        for t in tris.iter().filter(|t| keep(t)) {
            for &v in t {
                degree[v as usize].fetch_add(1, Ordering::Relaxed);
            }
        }
    });
    let links = VertexLinks::fill(triangles, degree, keep);
    (0..nv)
        .into_par_iter()
        .with_min_len(CHUNK)
        .fold(
            || (LinkCounts::default(), Scratch::default()),
            |(mut counts, mut scratch), v| {
                counts.add_vertex(v as u32, links.of(v), &mut scratch);
                (counts, scratch)
            },
        )
        .map(|(counts, _)| counts)
        .reduce(LinkCounts::default, LinkCounts::sum)
}

/// For every vertex, the triangles around it as the two other corners in winding order: a
/// triangle `(v, a, b)` puts `[a, b]` in the link of `v` (and `[b, v]` in that of `a`, …).
/// Compressed rows: the link of `v` is `link[start[v]..start[v + 1]]`, its entries in no
/// particular order.
struct VertexLinks {
    start: Vec<u32>,
    link: Vec<[u32; 2]>,
}

impl VertexLinks {
    /// The links of the triangles of `triangles` that pass `keep`, given each vertex's number
    /// of kept triangles (`degree`).
    fn fill(
        triangles: &[[u32; 3]],
        degree: Vec<AtomicU32>,
        keep: impl Fn(&[u32; 3]) -> bool + Sync,
    ) -> Self {
        // Exclusive prefix sum; `degree` becomes each row's fill cursor.
        let mut degree = degree;
        let mut start = Vec::with_capacity(degree.len() + 1);
        let mut sum = 0u32;
        for d in &mut degree {
            let d = d.get_mut();
            start.push(sum);
            (*d, sum) = (sum, sum + *d);
        }
        start.push(sum);
        let link: Vec<[AtomicU32; 2]> = (0..sum)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|_| [AtomicU32::new(0), AtomicU32::new(0)])
            .collect();
        triangles.par_chunks(CHUNK).for_each(|tris| {
            for t in tris {
                if !keep(t) {
                    continue;
                }
                for i in 0..3 {
                    let slot = degree[t[i] as usize].fetch_add(1, Ordering::Relaxed) as usize;
                    link[slot][0].store(t[(i + 1) % 3], Ordering::Relaxed);
                    link[slot][1].store(t[(i + 2) % 3], Ordering::Relaxed);
                }
            }
        });
        let link = link
            .into_iter()
            .map(|[a, b]| [a.into_inner(), b.into_inner()])
            .collect();
        Self { start, link }
    }

    /// The link of vertex `v`.
    fn of(&self, v: usize) -> &[[u32; 2]] {
        &self.link[self.start[v] as usize..self.start[v + 1] as usize]
    }
}
