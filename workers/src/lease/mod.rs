//! Leases: a file per shard naming the worker that processes it, refreshed by a heartbeat
//! and valid until it expires. They keep two workers off one shard, also across machines on a
//! shared filesystem. A lease file appears whole: it is written under a temporary name and
//! hard-linked into place (which fails if a lease exists), and heartbeats replace it
//! atomically. So a lease that does not parse (garbage, zero bytes) was damaged from outside
//! and is stale by definition, like one whose holder is gone (expired, or a process of this
//! host that no longer exists or is a zombie). A stale lease is taken over: renamed away (only
//! one taker's rename succeeds), then created anew.
//!
//! A lease keeps workers apart; it does not by itself keep a stopped holder from writing once
//! it is continued. That is fencing: the holder checks its lease before each write
//! (`held`), and every write that could still happen between a check and the write lands
//! in a file of that holder's own or is a create that fails when the target exists
//! (docs/RELIABILITY.md, "Fencing a holder that lost its lease").

mod held;

pub use held::{Lease, Loss};

use crate::error::{Result, WorkerError};
use serde::{Deserialize, Serialize};
use std::fs::OpenOptions;
use std::io::Write;
use std::path::Path;

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
    /// Unix time this holder took the lease: of two holders, the later one holds it (0 in
    /// leases written by earlier builds).
    #[serde(default)]
    pub acquired_at: f64,
}

impl LeaseInfo {
    /// Whether the holder is gone: expired, or a process of this host that no longer exists.
    pub fn is_stale(&self, now: f64) -> bool {
        if now > self.expires_at {
            return true;
        }
        self.host == hostname() && !pid_alive(self.pid)
    }

    /// Whether the holder is the process `pid` of this host.
    pub fn is_held_by_local(&self, pid: u32) -> bool {
        self.pid == pid && self.host == hostname()
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

/// Whether a process of this host exists and is not a zombie (a process that has exited but
/// was not reaped yet holds its pid and nothing else).
fn pid_alive(pid: u32) -> bool {
    // SAFETY: signal 0 only checks whether the process exists.
    let rc = unsafe { libc::kill(pid as libc::pid_t, 0) };
    let exists = rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM);
    exists && !is_zombie(pid)
}

/// Whether `/proc/PID/stat` says the process is a zombie (`Z`) or dead (`X`).
fn is_zombie(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return false;
    };
    // "pid (comm) state ...": comm may hold spaces and parentheses; the state follows the
    // last ')'.
    let state = stat
        .rsplit_once(')')
        .and_then(|(_, rest)| rest.split_whitespace().next());
    matches!(state, Some("Z") | Some("X"))
}

/// Reads a lease file; `None` when absent or unreadable (damaged: stale by definition).
pub fn read(path: &Path) -> Option<LeaseInfo> {
    let bytes = std::fs::read(path).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// A fresh lease of this process for `owner`, valid for `ttl` seconds from now.
fn info(owner: &str, ttl: f64) -> LeaseInfo {
    let now = crate::clock::now();
    LeaseInfo {
        owner: owner.to_string(),
        host: hostname(),
        pid: std::process::id(),
        heartbeat_at: now,
        expires_at: now + ttl,
        acquired_at: now,
    }
}

fn json(i: &LeaseInfo) -> Vec<u8> {
    serde_json::to_vec(i).unwrap_or_default()
}

/// The outcome of [`acquire`].
#[derive(Debug)]
pub enum Acquired {
    /// The lease is ours; its heartbeat runs.
    Held(Lease),
    /// A live worker holds it.
    Busy(LeaseInfo),
    /// Other takers kept changing it while we tried: treat the shard as busy and look again
    /// later.
    Contended,
}

/// Takes over a lease at most this many times in one [`acquire`] before calling it contended.
const TAKEOVER_TRIES: usize = 8;

/// Creates the lease file whole: written under a temporary name, then hard-linked to `path`
/// (which fails when a lease exists). `Ok(false)` when a lease exists. File systems without
/// hard links fall back to an exclusive create and a write.
fn create(path: &Path, content: &[u8], owner: &str) -> std::io::Result<bool> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.new-{}", sanitize(owner)));
    let linked = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(content)?;
        f.sync_all()?;
        std::fs::hard_link(&tmp, path)
    })();
    let _ = std::fs::remove_file(&tmp);
    match linked {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) if crate::fsutil::hard_links_unsupported(&e) => {
            match OpenOptions::new().write(true).create_new(true).open(path) {
                Ok(mut f) => {
                    f.write_all(content)?;
                    f.sync_all()?;
                    Ok(true)
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
                Err(e) => Err(e),
            }
        }
        Err(e) => Err(e),
    }
}

/// Tries to acquire the lease at `path` for `owner`, taking over a stale or unreadable one.
/// Never fails because of another worker's lease, only on I/O errors of our own writes.
pub fn acquire(path: &Path, owner: &str, ttl: f64) -> Result<Acquired> {
    for _ in 0..TAKEOVER_TRIES {
        let fresh = info(owner, ttl);
        let content = json(&fresh);
        if create(path, &content, owner).map_err(|e| WorkerError::io("creating lease", path, e))? {
            return Ok(Acquired::Held(Lease::start(path, &fresh, ttl)));
        }
        if let Some(h) = read(path).filter(|h| !h.is_stale(crate::clock::now())) {
            return Ok(Acquired::Busy(h));
        }
        // Stale or unreadable: take it over. Only one of several takers' renames succeeds.
        let aside = path.with_extension(format!("stale-{}", sanitize(owner)));
        if std::fs::rename(path, &aside).is_err() {
            continue;
        }
        // Between our look and our rename another taker may have put a fresh lease there:
        // give a live one back rather than stealing it.
        match read(&aside).filter(|h| !h.is_stale(crate::clock::now())) {
            Some(h) => {
                let _ = std::fs::hard_link(&aside, path);
                let _ = std::fs::remove_file(&aside);
                return Ok(Acquired::Busy(h));
            }
            None => {
                let _ = std::fs::remove_file(&aside);
            }
        }
    }
    Ok(Acquired::Contended)
}

fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}

/// An owner name as a token for file names: letters, digits, `-` and `.` kept, the rest `_`
/// (files named by it are created exclusively, so two owners never share one).
pub fn file_token(owner: &str) -> String {
    owner
        .chars()
        .map(|c| match c {
            'a'..='z' | 'A'..='Z' | '0'..='9' | '-' | '.' => c,
            _ => '_',
        })
        .collect()
}

/// A unique owner name for this process.
pub fn owner_name() -> String {
    let nonce = crate::clock::since_epoch().subsec_nanos();
    format!("{}:{}:{nonce:08x}", hostname(), std::process::id())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn second_taker_is_refused_and_stale_lease_is_taken_over() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("l");
        let Acquired::Held(a) = acquire(&path, "a", 60.0)? else {
            panic!("a free lease is taken")
        };
        assert!(matches!(acquire(&path, "b", 60.0)?, Acquired::Busy(h) if h.owner == "a"));
        a.release();
        assert!(!path.exists());
        // An expired lease.
        let old = LeaseInfo {
            owner: "ghost".into(),
            host: "elsewhere".into(),
            pid: 1,
            heartbeat_at: 0.0,
            expires_at: 1.0,
            acquired_at: 0.0,
        };
        std::fs::write(&path, json(&old)).map_err(|e| WorkerError::io("t", &path, e))?;
        let Acquired::Held(c) = acquire(&path, "c", 60.0)? else {
            panic!("an expired lease is taken over")
        };
        assert_eq!(read(&path).map(|h| h.owner), Some("c".to_string()));
        c.release();
        Ok(())
    }

    /// Issue 10, item 5: a lease holding garbage or zero bytes is stale by definition and
    /// taken over at once.
    #[test]
    fn unreadable_lease_is_taken_over_at_once() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("l");
        for junk in [&b""[..], b"\x00\xff garbage {", b"{\"owner\":"] {
            std::fs::write(&path, junk).map_err(|e| WorkerError::io("t", &path, e))?;
            let Acquired::Held(l) = acquire(&path, "me", 60.0)? else {
                panic!("{junk:?}: not taken over")
            };
            assert_eq!(read(&path).map(|h| h.owner), Some("me".to_string()));
            l.release();
        }
        Ok(())
    }

    /// Issue 10, item 3: a lease of a zombie process (exited, not reaped) is stale.
    #[test]
    fn lease_of_a_zombie_is_stale() -> Result<()> {
        let mut child = std::process::Command::new("true")
            .spawn()
            .map_err(|e| WorkerError::io("spawning", "true", e))?;
        // Not reaped yet: wait until it has exited and is a zombie.
        let pid = child.id();
        for _ in 0..200 {
            if is_zombie(pid) {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(is_zombie(pid), "the child did not become a zombie");
        let lease = LeaseInfo {
            owner: "zombie".into(),
            host: hostname(),
            pid,
            heartbeat_at: crate::clock::now(),
            expires_at: crate::clock::now() + 60.0,
            acquired_at: crate::clock::now(),
        };
        assert!(lease.is_stale(crate::clock::now()));
        let _ = child.wait();
        let me = LeaseInfo {
            pid: std::process::id(),
            ..lease
        };
        assert!(!me.is_stale(crate::clock::now()));
        Ok(())
    }
}
