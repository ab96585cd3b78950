//! What exports of a folder that were killed left beside it (issue 64 item 7), and the swap
//! of a finished export into place.
//!
//! An export is built in `.NAME.partial-PID` and an earlier export at the destination moved
//! aside to `.NAME.old-PID` while the new one takes its place. [`clear`] removes the folders
//! of processes that are gone (a `kill -9` leaves them), and moves a `.NAME.old-PID` back to
//! the destination when nothing is there (a kill between the two renames of an export made
//! before the swap was one step). [`exchange`] swaps the finished export and the earlier one
//! in one step (`renameat2` with `RENAME_EXCHANGE`), so the destination always holds a whole
//! export. Neither prints: what [`clear`] did comes back as lines for the caller to show.

use super::{io, RECORD};
use crate::Result;
use std::path::Path;

/// Clears the debris of killed exports of `out` beside it; returns the lines that say what
/// it did (`note: …`, `warning: …`), in the order it did it.
pub fn clear(out: &Path) -> Result<Vec<String>> {
    let mut said = Vec::new();
    let Some(name) = out.file_name() else {
        return Ok(said);
    };
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(parent) else {
        return Ok(said);
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some((kind, pid)) = file.strip_prefix(&prefix).and_then(|r| r.rsplit_once('-')) else {
            continue;
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        if !matches!(kind, "partial" | "old") || pid == std::process::id() || alive(pid) {
            continue;
        }
        said.push(clear_one(&entry.path(), kind, pid, out)?);
    }
    Ok(said)
}

/// Restores or removes one folder a killed export (process `pid`) left; what it did.
fn clear_one(path: &Path, kind: &str, pid: u32, out: &Path) -> Result<String> {
    if kind == "old" && !out.exists() && path.join(RECORD).is_file() {
        std::fs::rename(path, out).map_err(io(format!(
            "restoring {} to {}",
            path.display(),
            out.display()
        )))?;
        return Ok(format!(
            "note: {} was missing: the earlier export, which a killed export (process {pid}) \
             had moved aside to {}, is back in its place",
            out.display(),
            path.display()
        ));
    }
    // One that cannot be removed (read-only) is said and left: it takes nothing from the
    // export about to be made, whose own folders have this process's id.
    Ok(match std::fs::remove_dir_all(path) {
        Ok(()) => format!(
            "note: removed {}, left by an export that was killed (process {pid} is gone)",
            path.display()
        ),
        Err(e) => format!(
            "warning: {}, left by an export of process {pid} (gone), could not be removed \
             ({e}): remove it by hand",
            path.display()
        ),
    })
}

/// Whether process `pid` exists on this host (signal 0; a process of another user counts).
fn alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks whether the process exists.
    let rc = unsafe { libc::kill(pid, 0) };
    rc == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Swaps the folders `a` and `b` in one step; `Ok(false)` where the file system cannot (the
/// caller then renames in two steps).
pub(super) fn exchange(a: &Path, b: &Path) -> Result<bool> {
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes());
    let (ca, cb) = (c(a), c(b));
    let (Ok(ca), Ok(cb)) = (ca, cb) else {
        return Ok(false);
    };
    // SAFETY: two NUL-terminated paths relative to the working directory.
    let rc = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            ca.as_ptr(),
            libc::AT_FDCWD,
            cb.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if rc == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EINVAL | libc::ENOSYS | libc::EOPNOTSUPP) => Ok(false),
        _ => Err(io(format!("swapping {} and {}", a.display(), b.display()))(
            e,
        )),
    }
}
