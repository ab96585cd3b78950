//! A union-find over the vertices that many threads join at once, for the component counts
//! of [`super::check`] and [`super::component_count`].

use super::CHUNK;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Union-find over the vertices (lock-free: a root is only ever linked under a smaller index,
/// by compare-and-swap, so no cycle can form and the sets do not depend on the thread count),
/// with the vertices some triangle uses marked.
pub(super) struct ComponentForest {
    parent: Vec<AtomicU32>,
    used: Vec<AtomicBool>,
}

impl ComponentForest {
    /// `nv` vertices, each a set of its own, none used.
    pub(super) fn new(nv: usize) -> Self {
        let parent = (0..nv as u32)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(AtomicU32::new)
            .collect();
        let used = (0..nv)
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|_| AtomicBool::new(false))
            .collect();
        Self { parent, used }
    }

    /// Marks the corners of `t` (all in range) used and joins their sets.
    #[inline]
    pub(super) fn join(&self, t: &[u32; 3]) {
        let mut root = find_shared(&self.parent, t[0]);
        self.used[t[0] as usize].store(true, Ordering::Relaxed);
        for &v in &t[1..] {
            self.used[v as usize].store(true, Ordering::Relaxed);
            root = unite_roots(&self.parent, root, find_shared(&self.parent, v));
        }
    }

    /// The number of sets with a used vertex.
    pub(super) fn used_sets(&self) -> u64 {
        (0..self.parent.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .filter(|&v| {
                self.used[v].load(Ordering::Relaxed)
                    && self.parent[v].load(Ordering::Relaxed) == v as u32
            })
            .count() as u64
    }
}

/// The root of `x`, halving the path on the way.
fn find_shared(parent: &[AtomicU32], mut x: u32) -> u32 {
    loop {
        let p = parent[x as usize].load(Ordering::Acquire);
        if p == x {
            return x;
        }
        let g = parent[p as usize].load(Ordering::Acquire);
        if g == p {
            return p;
        }
        // Only ever points `x` higher up its own tree; losing the race is harmless.
        let _ = parent[x as usize].compare_exchange(p, g, Ordering::AcqRel, Ordering::Relaxed);
        x = g;
    }
}

/// Joins the sets whose roots were found to be `a` and `b` (either may have been linked
/// under another since): the larger root goes under the smaller one, so no cycle can form
/// whatever the interleaving. Returns a vertex of the joined set, for the next join.
fn unite_roots(parent: &[AtomicU32], a: u32, b: u32) -> u32 {
    let (mut ra, mut rb) = (a, b);
    loop {
        if ra == rb {
            return ra;
        }
        let (hi, lo) = if ra > rb { (ra, rb) } else { (rb, ra) };
        if parent[hi as usize]
            .compare_exchange(hi, lo, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
        {
            return lo;
        }
        (ra, rb) = (find_shared(parent, ra), find_shared(parent, rb));
    }
}
