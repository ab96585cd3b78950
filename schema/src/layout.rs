//! Where things live in a job folder. Pure path arithmetic: no I/O.
//!
//! ```text
//! JOB/job.json                          config, fingerprint, counts (written by init)
//! JOB/manifest.jsonl                    frozen manifest, one FrozenItem per line
//! JOB/job.lock                          flock: shared by run/work, exclusive while `add` grows it
//! JOB/shards/part-NNNNN.parquet         a finished shard
//! JOB/shards/part-NNNNN.complete.json   its completion record (written last)
//! JOB/state/part-NNNNN.journals/H.journal  finished items of a shard in progress, one file
//!                                         per lease holder H (no worker writes another's)
//! JOB/state/part-NNNNN.journal          a shard's single journal as earlier builds wrote it
//!                                       (read when resuming, never written)
//! JOB/state/part-NNNNN.lease            who works on a shard, with heartbeat and expiry
//! JOB/quarantine/part-NNNNN-<time>/     a damaged shard and its record, moved aside
//! ```

use std::path::{Path, PathBuf};

/// The paths of one job folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobLayout {
    /// The job folder.
    pub root: PathBuf,
}

impl JobLayout {
    /// The layout of the job folder `root`.
    pub fn new(root: impl AsRef<Path>) -> Self {
        Self {
            root: root.as_ref().to_path_buf(),
        }
    }

    /// `job.json`.
    pub fn job_file(&self) -> PathBuf {
        self.root.join("job.json")
    }

    /// `manifest.jsonl`.
    pub fn manifest(&self) -> PathBuf {
        self.root.join("manifest.jsonl")
    }

    /// `shards/`.
    pub fn shards_dir(&self) -> PathBuf {
        self.root.join("shards")
    }

    /// `state/`.
    pub fn state_dir(&self) -> PathBuf {
        self.root.join("state")
    }

    /// Base name of a shard: `part-NNNNN`.
    pub fn shard_name(shard: u64) -> String {
        format!("part-{shard:05}")
    }

    /// The shard's Parquet file.
    pub fn shard_file(&self, shard: u64) -> PathBuf {
        self.shards_dir()
            .join(format!("{}.parquet", Self::shard_name(shard)))
    }

    /// The temporary name a shard is written to before its rename (unique per writer).
    pub fn shard_tmp(&self, shard: u64, writer: &str) -> PathBuf {
        self.shards_dir()
            .join(format!(".{}.parquet.tmp-{writer}", Self::shard_name(shard)))
    }

    /// The shard's completion record.
    pub fn completion(&self, shard: u64) -> PathBuf {
        self.shards_dir()
            .join(format!("{}.complete.json", Self::shard_name(shard)))
    }

    /// The single journal of a shard in progress as earlier versions wrote it: read when a
    /// job started by them is resumed, never written.
    pub fn journal(&self, shard: u64) -> PathBuf {
        self.state_dir()
            .join(format!("{}.journal", Self::shard_name(shard)))
    }

    /// The folder of a shard's journals, one per lease holder.
    pub fn journals_dir(&self, shard: u64) -> PathBuf {
        self.state_dir()
            .join(format!("{}.journals", Self::shard_name(shard)))
    }

    /// The journal of lease holder `holder` (a file-name-safe token) on a shard.
    pub fn holder_journal(&self, shard: u64, holder: &str) -> PathBuf {
        self.journals_dir(shard).join(format!("{holder}.journal"))
    }

    /// `quarantine/`: damaged shards moved aside (never deleted) to be converted again.
    pub fn quarantine_dir(&self) -> PathBuf {
        self.root.join("quarantine")
    }

    /// The job lock (`job.lock`): held shared by `run` and `work`, exclusive by `add`.
    pub fn job_lock(&self) -> PathBuf {
        self.root.join("job.lock")
    }

    /// The lease of a shard.
    pub fn lease(&self, shard: u64) -> PathBuf {
        self.state_dir()
            .join(format!("{}.lease", Self::shard_name(shard)))
    }
}
