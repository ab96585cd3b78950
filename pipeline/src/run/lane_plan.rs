//! How `run` spreads its lanes (`--workers` items converted at once in all) over the workers
//! it runs, one shard each: shards still queued get a lane each first, then every worker's
//! items left (running or not started) ask for one lane each, the worker furthest from its
//! need served first, and lanes nobody needs go to the workers anyway, where they become
//! threads for their last items ([`sparc3d_workers::shard::lanes::LaneBudget::threads_for`]). So a
//! job of one shard keeps every lane busy, and the tail of a job uses the cores that finished
//! workers left.

/// A running worker as the plan sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Holder {
    /// Items of its shard not finished yet (`None`: not known yet, as many as it gets).
    pub left: Option<u64>,
}

impl Holder {
    /// Lanes it can use at once.
    fn need(&self) -> usize {
        self.left.map_or(usize::MAX, |n| n.max(1) as usize)
    }
}

/// The lanes of each holder (at least one each), given `total` lanes and `queued` shards
/// waiting for a worker of their own (lanes kept free for them, one each, as far as `total`
/// allows beyond the holders' one each).
pub fn share(total: usize, holders: &[Holder], queued: usize) -> Vec<usize> {
    let mut lanes = vec![1usize; holders.len()];
    let reserved = queued.min(total.saturating_sub(holders.len()));
    let mut spare = total.saturating_sub(holders.len() + reserved);
    while spare > 0 {
        let hungriest = (0..holders.len())
            .filter(|&i| lanes[i] < holders[i].need())
            .max_by_key(|&i| (holders[i].need() - lanes[i], std::cmp::Reverse(i)));
        match hungriest {
            Some(i) => lanes[i] += 1,
            None => break,
        }
        spare -= 1;
    }
    if reserved == 0 && !holders.is_empty() {
        // Nobody needs more lanes: they become threads of the last items, spread evenly.
        for k in 0..spare {
            lanes[k % holders.len()] += 1;
        }
    }
    lanes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn left(n: &[Option<u64>]) -> Vec<Holder> {
        n.iter().map(|&left| Holder { left }).collect()
    }

    #[test]
    fn one_shard_takes_every_lane() {
        assert_eq!(share(2, &left(&[None]), 0), vec![2]);
        assert_eq!(share(16, &left(&[Some(38)]), 0), vec![16]);
    }

    #[test]
    fn queued_shards_keep_a_lane_each() {
        // Two running, three queued, 4 lanes: the two new ones get the free lanes.
        assert_eq!(share(4, &left(&[None, None]), 3), vec![1, 1]);
        // One queued: one lane kept for it, the last one to the hungriest.
        assert_eq!(share(4, &left(&[Some(2), Some(9)]), 1), vec![1, 2]);
    }

    #[test]
    fn the_hungriest_worker_gets_lanes_first_and_the_rest_become_threads() {
        assert_eq!(share(5, &left(&[Some(1), Some(3)]), 0), vec![2, 3]);
        assert_eq!(
            share(6, &left(&[Some(1), Some(1), Some(10)]), 0),
            vec![1, 1, 4]
        );
        // Nobody needs the last lanes: spread over the holders.
        assert_eq!(share(8, &left(&[Some(1), Some(2)]), 0), vec![4, 4]);
    }

    #[test]
    fn every_holder_keeps_a_lane_even_past_the_total() {
        assert_eq!(share(1, &left(&[Some(5), Some(5)]), 2), vec![1, 1]);
        assert!(share(3, &[], 5).is_empty());
    }
}
