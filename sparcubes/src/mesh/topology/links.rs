//! The links of every vertex at once, for any mesh: the general path of [`super::check`]
//! where the triangles do not come in an order that [`super::tiles`] can follow.
//!
//! A pass over the triangles counts each vertex's triangles (atomics), a prefix sum gives
//! each vertex its rows, a second pass fills them, and a pass over the vertices reads them.
//! This holds every link in memory at once (8 bytes per triangle corner).

use super::fan::{link_entries, LinkCounts, Scratch};
use super::{is_good, CHUNK};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// The edge and vertex defects of the good triangles of `triangles` (in range, not
/// degenerate), over `nv` vertices.
pub(super) fn link_counts(triangles: &[[u32; 3]], nv: usize) -> LinkCounts {
    let links = VertexLinks::new(triangles, nv);
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
    /// The links of the good triangles of `triangles`, over `nv` vertices.
    fn new(triangles: &[[u32; 3]], nv: usize) -> Self {
        let good = || {
            triangles
                .par_chunks(CHUNK)
                .flat_map_iter(|tris| tris.iter().filter(|t| is_good(t, nv)))
        };
        let mut degree: Vec<AtomicU32> = (0..nv)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|_| AtomicU32::new(0))
            .collect();
        good().for_each(|t| {
            for &v in t {
                degree[v as usize].fetch_add(1, Ordering::Relaxed);
            }
        });
        // Exclusive prefix sum; `degree` becomes each row's fill cursor.
        let mut start = Vec::with_capacity(nv + 1);
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
        good().for_each(|t| {
            for (v, [a, b]) in link_entries(t) {
                let slot = degree[v as usize].fetch_add(1, Ordering::Relaxed) as usize;
                link[slot][0].store(a, Ordering::Relaxed);
                link[slot][1].store(b, Ordering::Relaxed);
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
