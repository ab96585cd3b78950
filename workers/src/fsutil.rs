//! Durable file operations: fsync of files and folders, atomic replacement; the sha256 and
//! the stamp of a file.

use crate::error::{Result, WorkerError};
use sparc3d_schema::FileStamp;
use std::fs::File;
use std::io::Write;
use std::path::Path;

/// Fsyncs a folder so that renames and creations inside it are durable.
pub fn sync_dir(dir: &Path) -> Result<()> {
    let f = File::open(dir).map_err(|e| WorkerError::io("opening folder", dir, e))?;
    f.sync_all()
        .map_err(|e| WorkerError::io("syncing folder", dir, e))
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, fsync, rename,
/// fsync of the folder.
pub fn write_atomic(path: &Path, bytes: &[u8], stage: &'static str) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut f = File::create(&tmp).map_err(|e| WorkerError::io(stage, &tmp, e))?;
        f.write_all(bytes)
            .map_err(|e| WorkerError::io(stage, &tmp, e))?;
        f.sync_all().map_err(|e| WorkerError::io(stage, &tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| WorkerError::io(stage, path, e))?;
        sync_dir(dir)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Reads and parses a JSON file.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = std::fs::read(path).map_err(|e| WorkerError::io("reading", path, e))?;
    serde_json::from_slice(&bytes).map_err(|e| WorkerError::BadFile {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Creates a folder and its parents.
pub fn create_dir(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| WorkerError::io("creating folder", path, e))
}

/// Hex sha256 of a regular file's bytes ([`sparc3d_manifests::hash::file_sha256`]: a FIFO,
/// device or socket is refused at once instead of being read forever).
pub fn file_sha256(path: &Path) -> Result<String> {
    sparc3d_manifests::hash::file_sha256(path)
        .map_err(|e| WorkerError::io(e.stage, e.path, e.source))
}

/// Hex sha256 of bytes in memory (a source file as the worker read it).
pub fn bytes_sha256(bytes: &[u8]) -> String {
    sparc3d_schema::hex::sha256_hex(bytes)
}

/// The stamp of a file from its metadata: modification and change times and inode.
pub fn file_stamp(meta: &std::fs::Metadata) -> FileStamp {
    use std::os::unix::fs::MetadataExt;
    let ns = |s: i64, n: i64| s as i128 * 1_000_000_000 + n as i128;
    FileStamp {
        modified_ns: ns(meta.mtime(), meta.mtime_nsec()),
        changed_ns: ns(meta.ctime(), meta.ctime_nsec()),
        inode: meta.ino(),
    }
}

/// Whether a failed `hard_link` says the file system has no hard links (FAT, some network
/// and FUSE file systems), so the caller falls back to another way of writing.
pub fn hard_links_unsupported(e: &std::io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(libc::EPERM) | Some(libc::EOPNOTSUPP) | Some(libc::ENOSYS)
    )
}

/// Gives the file `from` the name `to` unless `to` exists: a hard link, which fails when the
/// target exists, so two writers never replace each other's file. `Ok(false)` when `to`
/// exists. On file systems without hard links, a rename after checking that `to` is absent
/// (which leaves a moment between the check and the rename).
pub fn link_no_replace(from: &Path, to: &Path) -> std::io::Result<bool> {
    match std::fs::hard_link(from, to) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
        Err(e) if hard_links_unsupported(&e) => {
            if to.symlink_metadata().is_ok() {
                return Ok(false);
            }
            std::fs::rename(from, to)?;
            Ok(true)
        }
        Err(e) => Err(e),
    }
}
