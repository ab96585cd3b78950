//! How many items of a shard convert at once (lanes) and with how many threads each: the share
//! of the machine a `work` process has. `run` gives each of its workers a share and moves the
//! lanes of finished workers to those with items left, through control lines on the worker's
//! standard input ([`follow_control`]); `work --lanes N` sets a fixed share.

use serde::{Deserialize, Serialize};
use std::io::BufRead;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// A worker's share of the machine, changed while it runs.
#[derive(Debug)]
pub struct LaneBudget {
    /// Items converted at once (at least 1).
    lanes: AtomicUsize,
    /// Threads per lane (0: the item worker's environment decides, e.g. `RAYON_NUM_THREADS`).
    threads: AtomicUsize,
}

/// One control line from the orchestrator: the worker's new share.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Share {
    /// Items converted at once.
    pub lanes: usize,
    /// Threads per lane (0: leave the environment's).
    pub threads: usize,
}

impl LaneBudget {
    /// A budget of `share`.
    pub fn new(share: Share) -> Arc<Self> {
        Arc::new(Self {
            lanes: AtomicUsize::new(share.lanes.max(1)),
            threads: AtomicUsize::new(share.threads),
        })
    }

    /// One item at a time, threads as the environment says: a worker on its own.
    pub fn single() -> Arc<Self> {
        Self::new(Share {
            lanes: 1,
            threads: 0,
        })
    }

    /// Items to convert at once now.
    pub fn lanes(&self) -> usize {
        self.lanes.load(Ordering::SeqCst).max(1)
    }

    /// Takes a new share.
    pub fn set(&self, share: Share) {
        self.threads.store(share.threads, Ordering::SeqCst);
        self.lanes.store(share.lanes.max(1), Ordering::SeqCst);
    }

    /// Threads for an item that starts while `concurrent` items (itself included) run: the
    /// share's cores (lanes × threads) divided among them, so the last items of a shard use
    /// the cores its finished lanes left. 0 when the environment decides.
    pub fn threads_for(&self, concurrent: usize) -> usize {
        let per_lane = self.threads.load(Ordering::SeqCst);
        if per_lane == 0 {
            return 0;
        }
        (self.lanes() * per_lane / concurrent.max(1)).max(1)
    }
}

/// Reads control lines (JSON [`Share`]s) from `input` in a background thread, applying each
/// to `budget`, until the input ends. A line that does not parse is ignored: the share only
/// tunes speed, never what is written.
pub fn follow_control<R: BufRead + Send + 'static>(input: R, budget: Arc<LaneBudget>) {
    let spawned = std::thread::Builder::new()
        .name("lane-control".into())
        .spawn(move || {
            for line in input.lines().map_while(std::io::Result::ok) {
                if let Ok(share) = serde_json::from_str::<Share>(&line) {
                    budget.set(share);
                }
            }
        });
    if let Err(e) = spawned {
        // The worker keeps the share it started with.
        eprintln!("warning: no control thread ({e}); keeping the starting number of lanes");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_items_share_the_cores_of_the_finished_lanes() {
        let b = LaneBudget::new(Share {
            lanes: 4,
            threads: 2,
        });
        assert_eq!(b.threads_for(4), 2);
        assert_eq!(b.threads_for(3), 2);
        assert_eq!(b.threads_for(2), 4);
        assert_eq!(b.threads_for(1), 8);
        assert_eq!(LaneBudget::single().threads_for(1), 0);
    }

    #[test]
    fn control_lines_change_the_share_and_bad_ones_are_ignored() {
        let b = LaneBudget::single();
        let input = b"{\"lanes\":3,\"threads\":1}\nnot json\n{\"lanes\":0,\"threads\":2}\n";
        let reader = std::io::Cursor::new(input.to_vec());
        follow_control(reader, b.clone());
        for _ in 0..200 {
            if b.threads_for(1) == 2 {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        // The last line: lanes 0 means 1, at 2 threads.
        assert_eq!((b.lanes(), b.threads_for(1)), (1, 2));
    }
}
