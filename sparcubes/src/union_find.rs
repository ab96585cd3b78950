//! Union–find whose roots are the smallest members of their sets, and the components it
//! numbers: the same numbering whatever the order the joins come in, so whatever the thread
//! count. Used by the enclosed regions, the sealed vertices and the sealing's pockets.

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
