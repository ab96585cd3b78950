//! A shard's lease in a bucket: an object (`state/part-NNNNN.lease`, the same JSON as a lease
//! file) taken with a create-if-absent write and renewed with a replace-if-unchanged write on
//! its ETag, the conditional writes S3, GCS and Azure each offer. Of two workers racing for a
//! lease exactly one write succeeds; a stale lease (expired, or of a process of this host that
//! is gone) is taken over by replacing exactly the version that was read, so two takers of one
//! stale lease cannot both win.
//!
//! The holder renews it from a heartbeat thread every third of its time to live. A renewal
//! that is refused means another worker took the lease over (it had expired), unless the
//! object holds this holder's own last write (whose answer was lost: then that version is
//! held); with no object there, the lease (or the bucket) was deleted. Either way the holder
//! has lost it, as it has when its expiry passes without a renewal (network cut, stopped
//! process). [`BucketLease::confirm`] renews at once, trying again while the lease is valid
//! when the bucket cannot be reached, and is the fence before a checkpoint and before the
//! shard's commit: what follows a confirmed renewal happens while the lease was held a moment
//! before, and the commit itself is a create-if-absent write, so a holder that lost its lease
//! in between cannot replace a shard another one finished.

use crate::keys;
use anyhow::{Context, Result};
use sparc3d_sources::objects::{Prefix, Version, WriteMode, Written};
use sparc3d_sources::FetchErrorKind;
use sparc3d_workers::lease::{hostname, LeaseInfo};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Takes over a stale lease at most this many times in one [`acquire`].
const TAKEOVER_TRIES: usize = 8;

/// The longest wait between two tries of a renewal that could not reach the bucket.
const RENEW_WAIT_MAX: Duration = Duration::from_secs(5);

/// Why a renewal did not renew.
#[derive(Debug)]
enum Renewal {
    /// The lease is this worker's no more (taken over, expired, or its object gone).
    Lost(String),
    /// The bucket could not be written or read; the lease may still be held.
    Failed(String),
}

/// The outcome of [`acquire`].
#[derive(Debug)]
pub enum Acquired {
    /// The lease is ours; its heartbeat runs.
    Held(BucketLease),
    /// A live worker holds it.
    Busy(LeaseInfo),
    /// Other takers kept changing it while we tried.
    Contended,
}

/// What the heartbeat and the holder share.
#[derive(Debug)]
struct Shared {
    /// The lease version this holder wrote last, and its expiry.
    version: Mutex<(Version, f64)>,
    /// Why the lease is lost, once it is.
    lost: Mutex<Option<String>>,
    stop: AtomicBool,
    /// Set when the lease is lost, to stop the shard's item loop.
    on_loss: Arc<AtomicBool>,
}

/// A lease this worker holds in the bucket; its heartbeat runs until it is released.
#[derive(Debug)]
pub struct BucketLease {
    prefix: Prefix<'static>,
    shard: u64,
    owner: String,
    acquired_at: f64,
    ttl: f64,
    shared: Arc<Shared>,
    heartbeat: Option<JoinHandle<()>>,
}

fn fresh(owner: &str, ttl: f64, acquired_at: f64) -> LeaseInfo {
    let now = sparc3d_workers::clock::now();
    LeaseInfo {
        owner: owner.to_string(),
        host: hostname(),
        pid: std::process::id(),
        heartbeat_at: now,
        expires_at: now + ttl,
        acquired_at,
    }
}

fn bytes(info: &LeaseInfo) -> Vec<u8> {
    serde_json::to_vec(info).unwrap_or_default()
}

/// Tries to take the lease of `shard` for `owner` (`ttl` seconds without a renewal);
/// `on_loss` is set if the lease is lost later. Fails only when the bucket cannot be read or
/// written.
pub fn acquire(
    prefix: &Prefix<'static>,
    shard: u64,
    owner: &str,
    ttl: f64,
    on_loss: Arc<AtomicBool>,
) -> Result<Acquired> {
    let key = keys::lease(shard);
    let now = sparc3d_workers::clock::now();
    for _ in 0..TAKEOVER_TRIES {
        let mine = fresh(owner, ttl, now);
        if let Written::Done(version) = prefix.put(&key, bytes(&mine), WriteMode::Create)? {
            return Ok(Acquired::Held(BucketLease::start(
                prefix, shard, &mine, version, ttl, on_loss,
            )));
        }
        let Some(current) = prefix.get(&key)? else {
            continue; // released meanwhile
        };
        let holder: Option<LeaseInfo> = serde_json::from_slice(&current.bytes).ok();
        if let Some(h) = holder.filter(|h| !h.is_stale(sparc3d_workers::clock::now())) {
            return Ok(Acquired::Busy(h));
        }
        if current.version.etag.is_none() && current.version.version.is_none() {
            anyhow::bail!(
                "{}: the store gives no ETag or version, so a stale lease cannot be taken over \
                 safely",
                prefix.url(&key)
            );
        }
        let replace = WriteMode::Replace(current.version);
        if let Written::Done(version) = prefix.put(&key, bytes(&mine), replace)? {
            return Ok(Acquired::Held(BucketLease::start(
                prefix, shard, &mine, version, ttl, on_loss,
            )));
        }
    }
    Ok(Acquired::Contended)
}

impl BucketLease {
    fn start(
        prefix: &Prefix<'static>,
        shard: u64,
        info: &LeaseInfo,
        version: Version,
        ttl: f64,
        on_loss: Arc<AtomicBool>,
    ) -> Self {
        let shared = Arc::new(Shared {
            version: Mutex::new((version, info.expires_at)),
            lost: Mutex::new(None),
            stop: AtomicBool::new(false),
            on_loss,
        });
        let mut lease = Self {
            prefix: prefix.clone(),
            shard,
            owner: info.owner.clone(),
            acquired_at: info.acquired_at,
            ttl,
            shared,
            heartbeat: None,
        };
        lease.heartbeat = Some(lease.spawn_heartbeat());
        lease
    }

    fn spawn_heartbeat(&self) -> JoinHandle<()> {
        let beat = self.beater();
        let shared = Arc::clone(&self.shared);
        let period = Duration::from_secs_f64((self.ttl / 3.0).max(0.05));
        std::thread::spawn(move || {
            let step = Duration::from_millis(50);
            let mut waited = Duration::ZERO;
            while !shared.stop.load(Ordering::SeqCst) {
                std::thread::sleep(step);
                waited += step;
                if waited >= period {
                    waited = Duration::ZERO;
                    let _ = beat.renew();
                }
            }
        })
    }

    fn beater(&self) -> Beater {
        Beater {
            prefix: self.prefix.clone(),
            key: keys::lease(self.shard),
            owner: self.owner.clone(),
            acquired_at: self.acquired_at,
            ttl: self.ttl,
            shared: Arc::clone(&self.shared),
        }
    }

    /// Renews the lease now: `Ok` while it is this worker's, else why it was lost. A renewal
    /// that cannot reach the bucket is tried again, with a wait doubling from 0.2 s, while the
    /// lease is still valid: a blip of the store shorter than what is left of the lease fails
    /// nothing; past its expiry the lease is lost.
    pub fn confirm(&self) -> std::result::Result<(), String> {
        let beater = self.beater();
        let mut wait = Duration::from_millis(200);
        loop {
            let failed = match beater.renew() {
                Ok(()) => return Ok(()),
                Err(Renewal::Lost(why)) => return Err(why),
                Err(Renewal::Failed(why)) => why,
            };
            let left = beater.left();
            if left <= 0.0 {
                let why = beater.check().unwrap_or_default();
                return Err(format!("{why}; the last renewal failed: {failed}"));
            }
            std::thread::sleep(wait.min(Duration::from_secs_f64(left)));
            wait = (wait * 2).min(RENEW_WAIT_MAX);
        }
    }

    /// Why the lease is lost, if it is (no I/O: the expiry is checked against the clock).
    pub fn lost(&self) -> Option<String> {
        self.beater().check()
    }

    /// Stops the heartbeat and deletes the lease object unless another worker holds it now.
    pub fn release(mut self) {
        self.stop_heartbeat();
        if self.lost().is_some() {
            return;
        }
        let key = keys::lease(self.shard);
        let ours = self.shared.version.lock().map(|v| v.0.clone()).ok();
        if let Ok(Some(current)) = self.prefix.get(&key) {
            if Some(current.version) == ours {
                let _ = self.prefix.delete(&key);
            }
        }
    }

    fn stop_heartbeat(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.heartbeat.take() {
            let _ = h.join();
        }
    }
}

impl Drop for BucketLease {
    fn drop(&mut self) {
        self.stop_heartbeat();
    }
}

/// What renews a lease: shared by the heartbeat thread and [`BucketLease::confirm`].
struct Beater {
    prefix: Prefix<'static>,
    key: String,
    owner: String,
    acquired_at: f64,
    ttl: f64,
    shared: Arc<Shared>,
}

impl Beater {
    fn lose(&self, why: String) -> String {
        if let Ok(mut lost) = self.shared.lost.lock() {
            lost.get_or_insert(why.clone());
        }
        self.shared.on_loss.store(true, Ordering::SeqCst);
        why
    }

    fn check(&self) -> Option<String> {
        if let Some(why) = self.shared.lost.lock().ok().and_then(|l| l.clone()) {
            return Some(why);
        }
        let expires_at = self.shared.version.lock().map(|v| v.1).unwrap_or(0.0);
        let now = sparc3d_workers::clock::now();
        (now > expires_at).then(|| {
            self.lose(format!(
                "lease {} expired {:.1} s ago without a renewal (the bucket could not be \
                 written, or this worker was stopped): another worker may hold the shard now",
                self.prefix.url(&self.key),
                now - expires_at
            ))
        })
    }

    /// The seconds left before the lease expires (no I/O).
    fn left(&self) -> f64 {
        let expires_at = self.shared.version.lock().map(|v| v.1).unwrap_or(0.0);
        expires_at - sparc3d_workers::clock::now()
    }

    fn gone(&self) -> Renewal {
        Renewal::Lost(self.lose(format!(
            "lease {} is gone: the lease object (or its bucket) was deleted while this worker \
             held it, so nothing more is written for the shard (was the job's prefix or bucket \
             deleted?)",
            self.prefix.url(&self.key)
        )))
    }

    /// One renewal: replaces exactly the version this holder wrote last.
    fn renew(&self) -> std::result::Result<(), Renewal> {
        if let Some(why) = self.check() {
            return Err(Renewal::Lost(why));
        }
        let Ok(mut version) = self.shared.version.lock() else {
            return Err(Renewal::Lost("lease state poisoned".into()));
        };
        let info = fresh(&self.owner, self.ttl, self.acquired_at);
        let mode = WriteMode::Replace(version.0.clone());
        match self.prefix.put(&self.key, bytes(&info), mode) {
            Ok(Written::Done(written)) => {
                *version = (written, info.expires_at);
                Ok(())
            }
            Ok(Written::Refused) => self.refused(&mut version),
            Err(e) if e.kind == FetchErrorKind::NotFound => Err(self.gone()),
            // Tried again by `confirm` and at the next beat; the expiry decides when it is lost.
            Err(e) => Err(Renewal::Failed(format!("renewing lease: {e}"))),
        }
    }

    /// After a refused renewal: the object holds another holder's lease (taken over), none
    /// (deleted), or this holder's own last write, whose answer was lost on the way (a cut
    /// connection, or a retry of a write that had landed): then that is the version held.
    fn refused(&self, version: &mut (Version, f64)) -> std::result::Result<(), Renewal> {
        let current = match self.prefix.get(&self.key) {
            Ok(Some(current)) => current,
            Ok(None) => return Err(self.gone()),
            Err(e) => return Err(Renewal::Failed(format!("reading the lease back: {e}"))),
        };
        let holder = serde_json::from_slice::<LeaseInfo>(&current.bytes).ok();
        // The owner name holds the host, the process and a nonce; `acquired_at` is compared
        // within a millisecond, as serde_json's default float parsing may miss the last bit.
        if let Some(mine) = holder.as_ref().filter(|h| {
            h.owner == self.owner
                && h.pid == std::process::id()
                && (h.acquired_at - self.acquired_at).abs() < 1e-3
        }) {
            *version = (current.version, mine.expires_at);
            return Ok(());
        }
        let now_held_by = holder
            .map(|h| format!(", and {} holds it now", h.owner))
            .unwrap_or_default();
        Err(Renewal::Lost(self.lose(format!(
            "lease {} was taken over by another worker{now_held_by}",
            self.prefix.url(&self.key)
        ))))
    }
}

/// The lease of `shard` as the bucket holds it, if any and readable.
pub fn read(prefix: &Prefix<'_>, shard: u64) -> Result<Option<LeaseInfo>> {
    let key = keys::lease(shard);
    let found = prefix
        .get(&key)
        .with_context(|| format!("reading {}", prefix.url(&key)))?;
    Ok(found.and_then(|o| serde_json::from_slice(&o.bytes).ok()))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use sparc3d_sources::location::Location;

    /// A prefix of a fresh in-memory store (with conditional writes, like S3).
    pub(crate) fn memory_prefix() -> Prefix<'static> {
        let fetcher = sparc3d_sources::shared().unwrap_or_else(|e| panic!("{e}"));
        let Ok(Location::Remote(root)) = Location::parse("s3://bkt/jobs/a/job.json") else {
            panic!("a bucket URL")
        };
        let root = root.sibling(".");
        let store = Arc::new(object_store::memory::InMemory::new());
        Prefix::with_store(fetcher, &root, store)
    }

    fn flag() -> Arc<AtomicBool> {
        Arc::new(AtomicBool::new(false))
    }

    #[test]
    fn one_of_two_takers_holds_a_lease_and_a_stale_one_is_taken_over() -> Result<()> {
        let prefix = memory_prefix();
        let Acquired::Held(a) = acquire(&prefix, 0, "a", 60.0, flag())? else {
            panic!("a free lease is taken")
        };
        assert!(
            matches!(acquire(&prefix, 0, "b", 60.0, flag())?, Acquired::Busy(h) if h.owner == "a")
        );
        a.release();
        assert!(read(&prefix, 0)?.is_none(), "a released lease is deleted");
        // An expired lease of another host.
        let old = LeaseInfo {
            owner: "ghost".into(),
            host: "elsewhere".into(),
            pid: 1,
            heartbeat_at: 0.0,
            expires_at: 1.0,
            acquired_at: 0.0,
        };
        prefix.put(&keys::lease(0), bytes(&old), WriteMode::Overwrite)?;
        let Acquired::Held(c) = acquire(&prefix, 0, "c", 60.0, flag())? else {
            panic!("an expired lease is taken over")
        };
        assert_eq!(read(&prefix, 0)?.map(|h| h.owner), Some("c".to_string()));
        c.release();
        Ok(())
    }

    /// Issue 41, defect 7: a lease deleted under its holder (the bucket or the job's prefix
    /// deleted mid-run) is said to be gone, not taken over by another worker.
    #[test]
    fn a_deleted_lease_is_gone_not_taken_over() -> Result<()> {
        let prefix = memory_prefix();
        let stop = flag();
        let Acquired::Held(a) = acquire(&prefix, 2, "a", 60.0, Arc::clone(&stop))? else {
            panic!("a free lease is taken")
        };
        prefix.delete(&keys::lease(2))?;
        let why = a.confirm().expect_err("the renewal finds no lease");
        assert!(why.contains("is gone") && why.contains("deleted"), "{why}");
        assert!(!why.contains("taken over"), "{why}");
        assert!(stop.load(Ordering::SeqCst), "the item loop is told to stop");
        Ok(())
    }

    /// A renewal whose write landed but whose answer was lost (the connection cut on the way
    /// back, or a retry of it refused) finds its own lease there and holds it still.
    #[test]
    fn a_holder_that_finds_its_own_last_write_still_holds_the_lease() -> Result<()> {
        let prefix = memory_prefix();
        let stop = flag();
        let Acquired::Held(a) = acquire(&prefix, 4, "a", 60.0, Arc::clone(&stop))? else {
            panic!("a free lease is taken")
        };
        // The write of a renewal the holder never heard back from: its own lease, a new ETag.
        let Some(mine) = read(&prefix, 4)? else {
            panic!("the lease is there")
        };
        let landed = LeaseInfo {
            heartbeat_at: mine.heartbeat_at + 1.0,
            expires_at: mine.expires_at + 1.0,
            ..mine
        };
        prefix.put(&keys::lease(4), bytes(&landed), WriteMode::Overwrite)?;
        assert_eq!(a.confirm(), Ok(()), "its own write is not another worker's");
        assert_eq!(
            a.confirm(),
            Ok(()),
            "and the version read back is the one renewed"
        );
        assert!(a.lost().is_none() && !stop.load(Ordering::SeqCst));
        a.release();
        assert!(read(&prefix, 4)?.is_none());
        Ok(())
    }

    #[test]
    fn a_holder_whose_lease_was_taken_over_finds_it_lost_and_stops() -> Result<()> {
        let prefix = memory_prefix();
        let stop = flag();
        let Acquired::Held(a) = acquire(&prefix, 3, "a", 60.0, Arc::clone(&stop))? else {
            panic!("a free lease is taken")
        };
        assert_eq!(a.confirm(), Ok(()));
        // Another worker replaces it (as a taker of an expired lease would).
        let theirs = fresh("b", 60.0, sparc3d_workers::clock::now());
        prefix.put(&keys::lease(3), bytes(&theirs), WriteMode::Overwrite)?;
        let why = a.confirm().expect_err("the renewal is refused");
        assert!(
            why.contains("taken over") && why.contains("b holds it"),
            "{why}"
        );
        assert!(stop.load(Ordering::SeqCst), "the item loop is told to stop");
        assert!(a.lost().is_some());
        a.release();
        assert_eq!(
            read(&prefix, 3)?.map(|h| h.owner),
            Some("b".to_string()),
            "a lost lease is never deleted by its old holder"
        );
        Ok(())
    }
}
