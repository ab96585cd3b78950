//! Leases: a file per shard naming the worker that processes it, refreshed by a heartbeat
//! and valid until it expires. They keep two workers off one shard, also across machines on a
//! shared filesystem. A lease whose holder is gone (expired, or a dead process on this host)
//! is taken over: renamed away (only one taker's rename succeeds), then created anew.

use crate::error::{Result, WorkerError};
use serde::{Deserialize, Serialize};
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Content of a lease file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LeaseInfo {
    /// Unique owner name: `host:pid:nonce`.
    pub owner: String,
    /// Host name of the holder.
    pub host: String,
    /// Process id of the holder.
    pub pid: u32,
    /// Unix time of the last heartbeat.
    pub heartbeat_at: f64,
    /// Unix time after which the lease is stale.
    pub expires_at: f64,
}

impl LeaseInfo {
    /// Whether the holder is gone: expired, or a process of this host that no longer exists.
    pub fn is_stale(&self, now: f64) -> bool {
        if now > self.expires_at {
            return true;
        }
        self.host == hostname() && !pid_alive(self.pid)
    }
}

/// This machine's host name.
pub fn hostname() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; gethostname writes at most that much.
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr() as *mut libc::c_char, buf.len()) };
    if rc != 0 {
        return "unknown".into();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

fn pid_alive(pid: u32) -> bool {
    // SAFETY: signal 0 only checks whether the process exists.
    let rc = unsafe { libc::kill(pid as libc::pid_t, 0) };
    rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Reads a lease file; `None` when absent or unreadable (a torn write).
pub fn read(path: &Path) -> Option<LeaseInfo> {
    let bytes = std::fs::read(path).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// A held lease; the heartbeat runs until it is dropped or released.
#[derive(Debug)]
pub struct Lease {
    path: PathBuf,
    owner: String,
    stop: Arc<AtomicBool>,
    lost: Arc<Mutex<Option<String>>>,
    heartbeat: Option<JoinHandle<()>>,
}

fn info(owner: &str, ttl: f64) -> LeaseInfo {
    let now = crate::now();
    LeaseInfo {
        owner: owner.to_string(),
        host: hostname(),
        pid: std::process::id(),
        heartbeat_at: now,
        expires_at: now + ttl,
    }
}

fn json(i: &LeaseInfo) -> Vec<u8> {
    serde_json::to_vec(i).unwrap_or_default()
}

/// Tries to acquire the lease at `path`: `Ok(Ok(lease))`, or `Ok(Err(holder))` when a live
/// worker holds it.
pub fn acquire(
    path: &Path,
    owner: &str,
    ttl: f64,
) -> Result<std::result::Result<Lease, LeaseInfo>> {
    for _ in 0..3 {
        match OpenOptions::new().write(true).create_new(true).open(path) {
            Ok(mut f) => {
                f.write_all(&json(&info(owner, ttl)))
                    .and_then(|_| f.sync_all())
                    .map_err(|e| WorkerError::io("writing lease", path, e))?;
                return Ok(Ok(Lease::start(path, owner, ttl)));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let holder = read(path);
                let stale = match &holder {
                    Some(h) => h.is_stale(crate::now()),
                    None => file_age(path).is_some_and(|age| age > ttl),
                };
                if !stale {
                    if let Some(h) = holder {
                        return Ok(Err(h));
                    }
                    // Being written right now: let the writer finish.
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                }
                // Take over: only one of several takers' renames succeeds.
                let aside = path.with_extension(format!("stale-{}", sanitize(owner)));
                if std::fs::rename(path, &aside).is_ok() {
                    let _ = std::fs::remove_file(&aside);
                }
            }
            Err(e) => return Err(WorkerError::io("creating lease", path, e)),
        }
    }
    match read(path) {
        Some(h) => Ok(Err(h)),
        None => Err(WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: "could not acquire the lease after three tries".into(),
        }),
    }
}

fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

fn file_age(path: &Path) -> Option<f64> {
    let modified = std::fs::metadata(path).ok()?.modified().ok()?;
    Some(modified.elapsed().ok()?.as_secs_f64())
}

impl Lease {
    fn start(path: &Path, owner: &str, ttl: f64) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let lost = Arc::new(Mutex::new(None));
        let (p, o, s, l) = (
            path.to_path_buf(),
            owner.to_string(),
            stop.clone(),
            lost.clone(),
        );
        let period = Duration::from_secs_f64((ttl / 4.0).clamp(0.05, 30.0));
        let heartbeat = std::thread::Builder::new()
            .name("lease-heartbeat".into())
            .spawn(move || {
                let tick = Duration::from_millis(50).min(period);
                let mut waited = Duration::ZERO;
                while !s.load(Ordering::SeqCst) {
                    // Woken early by `stop_heartbeat`, so releasing a lease does not wait.
                    let t0 = std::time::Instant::now();
                    std::thread::park_timeout(tick);
                    if s.load(Ordering::SeqCst) {
                        return;
                    }
                    waited += t0.elapsed();
                    if waited < period {
                        continue;
                    }
                    waited = Duration::ZERO;
                    match read(&p) {
                        Some(h) if h.owner != o => {
                            if let Ok(mut g) = l.lock() {
                                *g = Some(h.owner);
                            }
                            return;
                        }
                        _ => {
                            // A failed heartbeat is retried; expiry protects the others.
                            let _ = crate::fsutil::write_atomic(&p, &json(&info(&o, ttl)), "lease");
                        }
                    }
                }
            })
            .ok();
        Self {
            path: path.to_path_buf(),
            owner: owner.to_string(),
            stop,
            lost,
            heartbeat,
        }
    }

    /// `Some(new owner)` when another worker took the lease over.
    pub fn lost_to(&self) -> Option<String> {
        self.lost.lock().ok().and_then(|g| g.clone())
    }

    /// The owner name.
    pub fn owner(&self) -> &str {
        &self.owner
    }

    /// Stops the heartbeat and removes the lease file if it is still ours.
    pub fn release(mut self) {
        self.stop_heartbeat();
        if read(&self.path).is_some_and(|h| h.owner == self.owner) {
            let _ = std::fs::remove_file(&self.path);
        }
    }

    fn stop_heartbeat(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
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

/// A unique owner name for this process.
pub fn owner_name() -> String {
    let nonce = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!("{}:{}:{nonce:08x}", hostname(), std::process::id())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_taker_is_refused_and_stale_lease_is_taken_over() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("l");
        let a = acquire(&path, "a", 60.0)?.map_err(|h| WorkerError::Child(h.owner))?;
        assert!(matches!(acquire(&path, "b", 60.0)?, Err(h) if h.owner == "a"));
        a.release();
        assert!(!path.exists());
        // An expired lease.
        let old = LeaseInfo {
            owner: "ghost".into(),
            host: "elsewhere".into(),
            pid: 1,
            heartbeat_at: 0.0,
            expires_at: 1.0,
        };
        std::fs::write(&path, json(&old)).map_err(|e| WorkerError::io("t", &path, e))?;
        let c = acquire(&path, "c", 60.0)?.map_err(|h| WorkerError::Child(h.owner))?;
        assert_eq!(read(&path).map(|h| h.owner), Some("c".to_string()));
        c.release();
        Ok(())
    }
}
