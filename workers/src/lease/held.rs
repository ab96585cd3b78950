//! A lease this process holds: its heartbeat, and the rule that fences a holder that lost it.
//!
//! A holder loses its lease when its expiry passes without a heartbeat (the process was
//! stopped, suspended or starved: from then on another worker may take the shard over, so
//! the holder cannot know what happened meanwhile) or when the lease file names a holder that
//! took it later. Both are checked by [`Lease::check`] before every journal append and before
//! the shard is committed, and polled by the item loop ([`Lease::is_lost`]). The first needs no
//! I/O: a stopped worker that is continued knows at once that it lost its lease.
//!
//! A lost lease is never renewed, written or removed by its old holder: a heartbeat checks
//! right before it renames its renewal into place. A holder that finds the file rewritten by
//! an *earlier* holder (a stale heartbeat stopped between that check and its rename) writes
//! its own again at once: the latest taker wins.

use super::{info, json, read, LeaseInfo};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Why a held lease is no longer this worker's: the lease file and what happened.
#[derive(Debug, Clone, PartialEq)]
pub struct Loss {
    /// The lease file.
    pub lease: PathBuf,
    /// What happened, naming the new holder when there is one.
    pub why: String,
}

/// What the heartbeat and the checks share.
#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    /// Set by a check that found the lease file rewritten by an earlier holder: renew now.
    beat_now: AtomicBool,
    /// Unix time (f64 bits) at which the last lease written by this holder expires.
    expires_at: AtomicU64,
    lost: Mutex<Option<String>>,
}

impl Shared {
    fn expires_at(&self) -> f64 {
        f64::from_bits(self.expires_at.load(Ordering::SeqCst))
    }

    fn lose(&self, why: String) {
        if let Ok(mut g) = self.lost.lock() {
            g.get_or_insert(why);
        }
    }

    fn lost(&self) -> Option<String> {
        self.lost.lock().ok().and_then(|g| g.clone())
    }
}

/// A held lease; the heartbeat runs until it is dropped or released.
#[derive(Debug)]
pub struct Lease {
    path: PathBuf,
    owner: String,
    acquired_at: f64,
    shared: Arc<Shared>,
    heartbeat: Option<JoinHandle<()>>,
}

/// The current holder named by the lease file, for a message ("" when none is readable).
fn holder_now(path: &Path, owner: &str) -> String {
    match read(path) {
        Some(h) if h.owner != owner => format!(", and {} holds it now", h.owner),
        _ => String::new(),
    }
}

/// Why the lease written at `expires_at` counts as lost at `now`, if it does.
fn expired(path: &Path, owner: &str, expires_at: f64, now: f64) -> Option<String> {
    (now > expires_at).then(|| {
        format!(
            "it expired {:.1} s ago without a heartbeat (this worker was stopped, suspended or \
             starved past it){}",
            now - expires_at,
            holder_now(path, owner)
        )
    })
}

/// Why the lease file `found` means this holder (`owner`, acquired at `acquired_at`) lost it.
fn taken(found: &LeaseInfo, owner: &str, acquired_at: f64) -> Option<String> {
    (found.owner != owner && found.acquired_at >= acquired_at)
        .then(|| format!("{} took it over", found.owner))
}

impl Lease {
    /// Starts the heartbeat of the lease just written as `first`.
    pub(super) fn start(path: &Path, first: &LeaseInfo, ttl: f64) -> Self {
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            beat_now: AtomicBool::new(false),
            expires_at: AtomicU64::new(first.expires_at.to_bits()),
            lost: Mutex::new(None),
        });
        let (p, o, s, acquired_at) = (
            path.to_path_buf(),
            first.owner.clone(),
            shared.clone(),
            first.acquired_at,
        );
        let period = Duration::from_secs_f64((ttl / 4.0).clamp(0.05, 30.0));
        let heartbeat = std::thread::Builder::new()
            .name("lease-heartbeat".into())
            .spawn(move || heartbeat(&p, &o, acquired_at, ttl, period, &s))
            .ok();
        Self {
            path: path.to_path_buf(),
            owner: first.owner.clone(),
            acquired_at,
            shared,
            heartbeat,
        }
    }

    /// `Ok` while this worker holds the lease; else why not. Reads the lease file (one small
    /// read), after checking the expiry without I/O.
    pub fn check(&self) -> Result<(), Loss> {
        let loss = |why| Loss {
            lease: self.path.clone(),
            why,
        };
        if let Some(why) = self.shared.lost() {
            return Err(loss(why));
        }
        let expires_at = self.shared.expires_at();
        let found = match expired(&self.path, &self.owner, expires_at, crate::clock::now()) {
            Some(why) => Some(why),
            None => read(&self.path).and_then(|h| {
                let why = taken(&h, &self.owner, self.acquired_at);
                if why.is_none() && h.owner != self.owner {
                    // An earlier holder's stale heartbeat: write ours again now.
                    self.shared.beat_now.store(true, Ordering::SeqCst);
                    if let Some(t) = &self.heartbeat {
                        t.thread().unpark();
                    }
                }
                why
            }),
        };
        match found {
            Some(why) => {
                self.shared.lose(why.clone());
                Err(loss(why))
            }
            None => Ok(()),
        }
    }

    /// Whether the lease is known to be lost, without I/O (polled while an item converts).
    pub fn is_lost(&self) -> bool {
        self.shared.lost().is_some() || crate::clock::now() > self.shared.expires_at()
    }

    /// The owner name.
    pub fn owner(&self) -> &str {
        &self.owner
    }

    /// The lease file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Stops the heartbeat and removes the lease file if this worker still holds it (a lost
    /// lease is left to its new holder).
    pub fn release(mut self) {
        self.stop_heartbeat();
        if self.check().is_ok() && read(&self.path).is_some_and(|h| h.owner == self.owner) {
            let _ = std::fs::remove_file(&self.path);
        }
    }

    fn stop_heartbeat(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.heartbeat.take() {
            h.thread().unpark();
            let _ = h.join();
        }
    }
}

impl Drop for Lease {
    fn drop(&mut self) {
        self.stop_heartbeat();
    }
}

/// The heartbeat: every `period` (or at once when a check asks), unless stopped, renews the
/// lease at `p` while it is this holder's; records the loss and ends once it is not.
fn heartbeat(p: &Path, owner: &str, acquired_at: f64, ttl: f64, period: Duration, s: &Shared) {
    let tick = Duration::from_millis(50).min(period);
    let mut waited = Duration::ZERO;
    while !s.stop.load(Ordering::SeqCst) {
        // Woken early by `stop_heartbeat` (so releasing a lease does not wait) or by a check
        // that found the file rewritten by an earlier holder.
        let t0 = std::time::Instant::now();
        std::thread::park_timeout(tick);
        if s.stop.load(Ordering::SeqCst) {
            return;
        }
        waited += t0.elapsed();
        if waited < period && !s.beat_now.swap(false, Ordering::SeqCst) {
            continue;
        }
        waited = Duration::ZERO;
        let next = LeaseInfo {
            acquired_at,
            ..info(owner, ttl)
        };
        match renew(p, &next, s) {
            Ok(()) => s
                .expires_at
                .store(next.expires_at.to_bits(), Ordering::SeqCst),
            Err(Some(why)) => return s.lose(why),
            // A failed write is retried at the next beat; expiry protects the others.
            Err(None) => {}
        }
    }
}

/// Writes `next` over the lease at `p` (ours, absent, or rewritten by an earlier holder):
/// under a temporary name, fsynced, and renamed into place only after checking, right before
/// the rename, that the lease has not expired nor been taken (so that a holder stopped during
/// the slow part, the fsync, does not replace its successor's lease when continued).
/// `Err(Some(why))` when the lease is lost, `Err(None)` when the write failed.
fn renew(p: &Path, next: &LeaseInfo, s: &Shared) -> Result<(), Option<String>> {
    let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
    let tmp = p.with_file_name(format!(
        ".{}.beat-{}",
        name.unwrap_or_default(),
        super::file_token(&next.owner)
    ));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        std::io::Write::write_all(&mut f, &json(next))?;
        f.sync_all()
    });
    let lost = || {
        // An expired lease is never renewed: someone may be taking it over right now.
        expired(p, &next.owner, s.expires_at(), crate::clock::now())
            .or_else(|| read(p).and_then(|h| taken(&h, &next.owner, next.acquired_at)))
    };
    let result = match written {
        Err(_) => Err(None),
        Ok(()) => match lost() {
            Some(why) => Err(Some(why)),
            None => std::fs::rename(&tmp, p).map_err(|_| None),
        },
    };
    let _ = std::fs::remove_file(&tmp);
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::{Result, WorkerError};

    fn io(e: std::io::Error) -> WorkerError {
        WorkerError::io("test", "/tmp", e)
    }

    fn lease_of(owner: &str, acquired_at: f64, expires_at: f64) -> LeaseInfo {
        LeaseInfo {
            owner: owner.into(),
            host: "elsewhere".into(),
            pid: 1,
            heartbeat_at: acquired_at,
            expires_at,
            acquired_at,
        }
    }

    /// Issue 32, item 4: a holder whose lease expired without a heartbeat (it was stopped)
    /// has lost it, whatever the file says, and never renews or removes it.
    #[test]
    fn an_expired_lease_is_lost_and_left_alone() -> Result<()> {
        let dir = tempfile::tempdir().map_err(io)?;
        let path = dir.path().join("l");
        let now = crate::clock::now();
        let mine = LeaseInfo {
            expires_at: now - 5.0,
            ..info("me", 60.0)
        };
        std::fs::write(&path, json(&mine)).map_err(io)?;
        let held = Lease::start(&path, &mine, 60.0);
        assert!(held.is_lost());
        let loss = held.check().err().map(|l| l.why).unwrap_or_default();
        assert!(loss.starts_with("it expired 5."), "{loss}");
        held.release();
        assert_eq!(
            std::fs::read(&path).map_err(io)?,
            json(&mine),
            "a lost lease is neither renewed nor removed"
        );
        Ok(())
    }

    /// Issue 32, item 4: a lease file naming a holder that took the lease later means it is
    /// lost; one naming an earlier holder (a stale heartbeat) is overwritten by the next beat.
    #[test]
    fn the_later_taker_holds_the_lease() -> Result<()> {
        let dir = tempfile::tempdir().map_err(io)?;
        let path = dir.path().join("l");
        let mine = info("me", 0.4);
        std::fs::write(&path, json(&mine)).map_err(io)?;
        let held = Lease::start(&path, &mine, 0.4);
        let stale = lease_of("earlier", mine.acquired_at - 10.0, mine.expires_at + 60.0);
        std::fs::write(&path, json(&stale)).map_err(io)?;
        assert!(held.check().is_ok(), "an earlier holder does not take it");
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        while read(&path).is_some_and(|l| l.owner != "me") {
            assert!(std::time::Instant::now() < deadline, "never written again");
            std::thread::sleep(Duration::from_millis(20));
        }
        held.release();
        // A lease of 60 s: no beat during the rest of the test.
        let mine = info("me", 60.0);
        std::fs::write(&path, json(&mine)).map_err(io)?;
        let held = Lease::start(&path, &mine, 60.0);
        let later = lease_of("later", mine.acquired_at + 1.0, mine.expires_at);
        std::fs::write(&path, json(&later)).map_err(io)?;
        let loss = held.check().err().map(|l| l.why).unwrap_or_default();
        assert_eq!(loss, "later took it over");
        assert!(held.is_lost());
        held.release();
        assert_eq!(
            std::fs::read(&path).map_err(io)?,
            json(&later),
            "the new holder's lease stays"
        );
        Ok(())
    }
}
