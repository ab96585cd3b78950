//! Union–find whose roots are the smallest members of their sets, and the components it
//! numbers: the same numbering whatever the order the joins come in, so whatever the thread
//! count. Used by the enclosed regions, the sealed vertices and the sealing's pockets;
//! [`SharedSets`] takes joins from many threads at once (the enclosed regions, where the
//! joins of millions of parts were one thread's work).

use std::sync::atomic::{AtomicU32, Ordering};

/// A union–find over `0..n` whose roots are the smallest members of their sets (path
/// halving; a union links the larger root under the smaller).
pub(crate) struct Sets(Vec<u32>);

impl Sets {
    /// Every member in a set of its own.
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }

    /// The root of `x`'s set.
    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let up = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = up;
            x = up;
        }
        x
    }

    /// Joins the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.0[hi as usize] = lo;
        }
    }

    /// Each member's set, numbered in the order of the sets' smallest members, for the
    /// members `keep` holds (`u32::MAX` for the others), and the number of sets numbered.
    pub(crate) fn labels(&mut self, keep: impl Fn(usize) -> bool) -> (Vec<u32>, usize) {
        let len = self.0.len();
        let mut label = vec![u32::MAX; len];
        let mut count = 0u32;
        for q in 0..len {
            if !keep(q) {
                continue;
            }
            let root = self.find(q as u32) as usize;
            if root == q {
                label[q] = count;
                count += 1;
            } else {
                label[q] = label[root];
            }
        }
        (label, count as usize)
    }
}

/// The components of `len` items joined by `pairs`: each kept item's component (numbered in
/// the order of the components' smallest items, [`Sets::labels`]) and the number of
/// components. The same result whatever the order of `pairs`.
pub(crate) fn components(
    len: usize,
    pairs: &[(u32, u32)],
    keep: impl Fn(usize) -> bool,
) -> (Vec<u32>, usize) {
    let mut sets = Sets::new(len);
    for &(a, b) in pairs {
        sets.union(a, b);
    }
    sets.labels(keep)
}

/// A union–find over `0..n` that many threads join at once: the same rule as [`Sets`] (a
/// root is the smallest member of its set; a union links the larger root under the smaller,
/// only while it is still a root, else it looks again), with path halving done by
/// compare-and-swap. Parents only ever move to smaller members of the same set, so the sets
/// it ends with are the components of the joins, whatever their order and interleaving, and
/// [`SharedSets::into_sets`] numbers them as [`Sets::labels`] does.
pub(crate) struct SharedSets(Vec<AtomicU32>);

impl SharedSets {
    /// Every member in a set of its own.
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).map(AtomicU32::new).collect())
    }

    fn parent(&self, x: u32) -> u32 {
        self.0[x as usize].load(Ordering::Acquire)
    }

    /// The root of `x`'s set (at the time it is read: a concurrent union may link it under a
    /// smaller one just after).
    fn find(&self, mut x: u32) -> u32 {
        loop {
            let up = self.parent(x);
            if up == x {
                return x;
            }
            let grand = self.parent(up);
            if grand != up {
                // Halving: x skips to its grandparent unless another thread moved it already.
                let _ = self.0[x as usize].compare_exchange(
                    up,
                    grand,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                );
            }
            x = grand;
        }
    }

    /// Joins the sets of `a` and `b`; callable from many threads at once.
    pub(crate) fn union(&self, a: u32, b: u32) {
        let (mut a, mut b) = (a, b);
        loop {
            let (ra, rb) = (self.find(a), self.find(b));
            if ra == rb {
                return;
            }
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            let linked =
                self.0[hi as usize].compare_exchange(hi, lo, Ordering::AcqRel, Ordering::Acquire);
            if linked.is_ok() {
                return;
            }
            // `hi` was linked meanwhile: look again from the roots found.
            (a, b) = (ra, rb);
        }
    }

    /// The sets as a [`Sets`], once every join is done.
    pub(crate) fn into_sets(self) -> Sets {
        Sets(self.0.into_iter().map(AtomicU32::into_inner).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// The joins of `stride` chains over `0..n` (member i with i − stride), in a scrambled
    /// order, every other one reversed.
    fn pairs(n: u32, stride: u32) -> Vec<(u32, u32)> {
        let mut joins: Vec<(u32, u32)> = (stride..n)
            .map(|i| {
                if i % 2 == 0 {
                    (i, i - stride)
                } else {
                    (i - stride, i)
                }
            })
            .collect();
        joins.sort_by_key(|&(a, b)| a.max(b).wrapping_mul(2_654_435_761));
        joins
    }

    #[test]
    fn shared_sets_joined_from_many_threads_number_as_sets_joined_in_order() {
        let (n, stride) = (200_000u32, 7u32);
        let joins = pairs(n, stride);
        let expected = components(n as usize, &joins, |_| true);
        assert_eq!(expected.1, stride as usize);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build();
        let pool = match pool {
            Ok(pool) => pool,
            Err(e) => panic!("no thread pool: {e}"),
        };
        for _ in 0..3 {
            let shared = SharedSets::new(n as usize);
            pool.install(|| joins.par_iter().for_each(|&(a, b)| shared.union(a, b)));
            assert_eq!(shared.into_sets().labels(|_| true), expected);
        }
    }
}
