//! Errors of processing a shard. An item's failure is never an error here (it becomes a
//! `failed` row); these are failures of the job's own machinery: files, leases, config drift.

use std::path::{Path, PathBuf};

/// What stopped a shard from being processed.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// A file operation failed; `stage` says what was being done.
    #[error("{stage} {}: {source}{}", path.display(), hint(source))]
    Io {
        /// What was being done (e.g. "appending to journal").
        stage: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A job file is malformed.
    #[error("{}: {reason}", path.display())]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The shard or its journal was written with another config.
    #[error("{what} was written with config fingerprint {found}, this job's is {expected}; refusing to mix configs")]
    ConfigDrift {
        /// Which file.
        what: String,
        /// The fingerprint found.
        found: String,
        /// The job's fingerprint.
        expected: String,
    },
    /// This worker no longer holds the shard's lease (it was stopped or starved past it, or
    /// another worker took it over): it stops working on the shard and writes nothing more.
    #[error(
        "shard {shard}: this worker lost its lease {}: {why}; it stops here and leaves the \
         shard to the new holder (what it converted stays in its own journal file, which no \
         other worker writes)",
        lease.display()
    )]
    LeaseLost {
        /// Shard index.
        shard: u64,
        /// The lease file.
        lease: PathBuf,
        /// What happened, naming the new holder when there is one.
        why: String,
    },
    /// The job's own files no longer match what `init` recorded (hand edits): every command
    /// but a read-only one refuses the job.
    #[error(
        "{} was changed after `sparc3d init`, so this command refuses it: {}. Restore the \
         files as init wrote them, or make a new job folder; read-only commands (status, ls, \
         failures, inspect, show) still read it",
        root.display(),
        problems.join("; ")
    )]
    EditedJob {
        /// The job folder.
        root: PathBuf,
        /// What differs, one finding per file and fact.
        problems: Vec<String>,
    },
    /// The bucket that is the job's home could not be read or written (a checkpoint, an
    /// upload), after the store client's own retries.
    #[error("{0}")]
    Remote(String),
    /// The item worker process could not be started or talked to.
    #[error("item worker: {0}")]
    Child(String),
    /// Encoding or decoding a contract type failed.
    #[error(transparent)]
    Schema(#[from] sparc3d_schema::SchemaError),
    /// A shard file could not be read back; `stage` says what was being done.
    #[error("{stage} {}: {reason}", path.display())]
    ReadShard {
        /// What was being done ("opening", "reading", "decoding").
        stage: &'static str,
        /// The shard file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// A finished shard no longer matches its completion record.
    #[error(
        "shard {shard} of {root} is damaged: {why}; `sparc3d verify {root}` moves damaged \
         shards aside and `sparc3d run {root}` converts them again",
        root = root.display()
    )]
    Damaged {
        /// Shard index.
        shard: u64,
        /// The job folder.
        root: PathBuf,
        /// What does not match.
        why: String,
    },
    /// Writing Parquet failed.
    #[error("writing parquet {}: {source}{}", path.display(), parquet_hint(source))]
    Parquet {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: parquet::errors::ParquetError,
    },
}

/// What to do about an I/O error, for the end of its message (" (disk full: …)"), or nothing.
pub fn hint(e: &std::io::Error) -> String {
    errno_hint(e.raw_os_error())
}

/// The hint for an I/O error inside a Parquet error: the writer reports it wrapped, or only
/// as text (`... (os error 28)`).
fn parquet_hint(e: &parquet::errors::ParquetError) -> String {
    if let parquet::errors::ParquetError::External(inner) = e {
        if let Some(io) = inner.downcast_ref::<std::io::Error>() {
            return hint(io);
        }
    }
    let text = e.to_string();
    let errno = text
        .rsplit_once("(os error ")
        .and_then(|(_, rest)| rest.split(')').next())
        .and_then(|n| n.parse().ok());
    errno_hint(errno)
}

fn errno_hint(errno: Option<i32>) -> String {
    match errno {
        Some(libc::ENOSPC) | Some(libc::EDQUOT) => {
            " (disk full: free space and run again; finished items are kept)".into()
        }
        Some(libc::EFBIG) => {
            " (file size limit reached: raise the limit and run again; finished items are kept)"
                .into()
        }
        Some(libc::EACCES) | Some(libc::EROFS) | Some(libc::EPERM) => {
            " (output folder not writable: fix permissions and run again)".into()
        }
        Some(libc::EMFILE) => format!(
            " (this process's open-file limit is {}: raise it (`ulimit -n`) and run again; \
             finished items are kept)",
            open_file_limit()
        ),
        Some(libc::ENFILE) => {
            " (the system's open-file table is full: close files and run again; finished \
             items are kept)"
                .into()
        }
        _ => String::new(),
    }
}

/// The soft limit on this process's open files (`ulimit -n`), as text.
fn open_file_limit() -> String {
    let mut limit = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the struct it is given and reads nothing else.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } == 0;
    match (ok, limit.rlim_cur) {
        (false, _) => "unknown".into(),
        (true, libc::RLIM_INFINITY) => "unlimited".into(),
        (true, n) => n.to_string(),
    }
}

impl WorkerError {
    /// An I/O error with its stage and path.
    pub fn io(stage: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        WorkerError::Io {
            stage,
            path: path.into(),
            source,
        }
    }

    /// An error reading the shard file at `path`; `stage` says what was being done.
    pub(crate) fn read_shard(stage: &'static str, path: &Path, e: impl std::fmt::Display) -> Self {
        WorkerError::ReadShard {
            stage,
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    }
}

/// Result with [`WorkerError`].
pub type Result<T, E = WorkerError> = std::result::Result<T, E>;
