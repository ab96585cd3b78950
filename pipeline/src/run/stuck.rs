//! Whether a worker of `run` still makes progress, judged by its shard's lease: a worker
//! heartbeats its lease every quarter of its lifetime from a thread of its own, so a lease of
//! its own that expired means the worker was stopped (SIGSTOP, a debugger) or hung past it.
//! Such a worker is taken back: `run` kills it and starts the shard again on a new worker,
//! which takes the expired lease over and resumes from the journals (`pool.rs`).
//!
//! A worker whose shard's lease is another's (taken over while it was stopped) or gone is
//! stuck once it showed no sign of life (its own live lease, or an event) for a lease
//! lifetime: a live one ends by itself sooner, having lost the lease. One that never held the
//! lease (stopped while starting) gets [`NO_LEASE_LIFETIMES`] lifetimes, since reading a large
//! job can take a while.

use sparc3d_workers::lease::LeaseInfo;
use std::time::{Duration, Instant};

/// Lease lifetimes a worker that never held its shard's lease may show no sign of life.
pub const NO_LEASE_LIFETIMES: u32 = 10;

/// What `run` knows of one worker's progress.
#[derive(Debug)]
pub struct Watch {
    /// The last sign of life: its own live lease seen, or an event from it.
    alive_at: Instant,
    /// Whether its own lease was ever seen.
    held: bool,
    /// Whether it was judged stuck (and is being killed).
    taken_back: bool,
}

impl Watch {
    /// The watch of a worker started now.
    pub fn new() -> Self {
        Self {
            alive_at: Instant::now(),
            held: false,
            taken_back: false,
        }
    }

    /// The worker reported an event: it is alive.
    pub fn saw_event(&mut self) {
        self.alive_at = Instant::now();
    }

    /// Whether it was judged stuck.
    pub fn taken_back(&self) -> bool {
        self.taken_back
    }

    /// Looks at the lease of the worker's shard (`lease`, as its file says) at Unix time
    /// `now`, for the worker process `pid` whose leases live `ttl`; `Some(why)` the one time
    /// it is judged stuck.
    pub fn look(
        &mut self,
        lease: Option<&LeaseInfo>,
        pid: u32,
        now: f64,
        ttl: Duration,
    ) -> Option<String> {
        if self.taken_back {
            return None;
        }
        let why = match lease {
            Some(l) if l.is_held_by_local(pid) => {
                self.held = true;
                if now > l.expires_at {
                    Some(format!(
                        "its lease expired {:.1} s ago without a heartbeat: stopped or hung",
                        now - l.expires_at
                    ))
                } else {
                    self.alive_at = Instant::now();
                    None
                }
            }
            other => {
                let grace = if self.held {
                    ttl
                } else {
                    ttl * NO_LEASE_LIFETIMES
                };
                let quiet = self.alive_at.elapsed();
                (quiet > grace).then(|| {
                    let lease = match other {
                        Some(l) => format!("{} holds its shard's lease", l.owner),
                        None => "it holds no lease".to_string(),
                    };
                    format!(
                        "{lease}, and it showed no sign of life for {:.1} s",
                        quiet.as_secs_f64()
                    )
                })
            }
        };
        self.taken_back = why.is_some();
        why
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lease(pid: u32, expires_at: f64) -> LeaseInfo {
        LeaseInfo {
            owner: format!("here:{pid}:1"),
            host: sparc3d_workers::lease::hostname(),
            pid,
            heartbeat_at: expires_at - 60.0,
            expires_at,
            acquired_at: expires_at - 60.0,
        }
    }

    #[test]
    fn a_worker_whose_own_lease_expired_is_stuck_once() {
        let ttl = Duration::from_secs(60);
        let mut w = Watch::new();
        assert_eq!(w.look(Some(&lease(7, 100.0)), 7, 99.0, ttl), None);
        let why = w.look(Some(&lease(7, 100.0)), 7, 102.5, ttl);
        assert_eq!(
            why.as_deref(),
            Some("its lease expired 2.5 s ago without a heartbeat: stopped or hung")
        );
        assert!(w.taken_back());
        assert_eq!(
            w.look(Some(&lease(7, 100.0)), 7, 103.0, ttl),
            None,
            "said once"
        );
    }

    #[test]
    fn another_workers_lease_or_none_is_not_yet_a_reason() {
        let ttl = Duration::from_secs(60);
        let mut w = Watch::new();
        // A live lease of another process, none, an expired one of another process: this
        // worker is starting, or ending after losing its lease; it gets its lifetime.
        assert_eq!(w.look(Some(&lease(8, 100.0)), 7, 99.0, ttl), None);
        assert_eq!(w.look(None, 7, 99.0, ttl), None);
        assert_eq!(w.look(Some(&lease(8, 100.0)), 7, 200.0, ttl), None);
        assert!(!w.taken_back());
    }
}
