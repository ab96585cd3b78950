//! Where things live in a job folder. Pure path arithmetic: no I/O.
//!
//! ```text
//! JOB/job.json                          config, fingerprint, counts (written by init)
//! JOB/manifest/index-PPPPP.<sha>.tsv     a page of the frozen manifest's index: a line per
//!                                       shard (its first item, items, slice sha256)
//! JOB/manifest/part-NNNNN.<sha>.jsonl    a shard's slice of the frozen manifest, one
//!                                       FrozenItem per line (<sha>: 16 hex digits of the
//!                                       file's sha256; job.json pins the pages')
//! JOB/manifest.jsonl                    the frozen manifest in one file, as jobs made before
//!                                       slices have it (read, never written)
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

/// The first 16 hex digits of a sha256, as the frozen manifest's file names carry them.
fn short(sha256: &str) -> &str {
    sha256.get(..16).unwrap_or(sha256)
}

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

    /// `manifest.jsonl`: the frozen manifest of a job made before slices.
    pub fn manifest(&self) -> PathBuf {
        self.root.join("manifest.jsonl")
    }

    /// `manifest/`: the frozen manifest's slices and index pages.
    pub fn manifest_dir(&self) -> PathBuf {
        self.root.join(Self::MANIFEST_DIR)
    }

    /// The folder name of the frozen manifest's slices, relative to the job.
    pub const MANIFEST_DIR: &'static str = "manifest";

    /// The name (within `manifest/`) of index page `page` whose bytes have sha256 `sha256`.
    pub fn page_name(page: u64, sha256: &str) -> String {
        format!("index-{page:05}.{}.tsv", short(sha256))
    }

    /// The name (within `manifest/`) of `shard`'s slice whose bytes have sha256 `sha256`.
    pub fn slice_name(shard: u64, sha256: &str) -> String {
        format!("{}.{}.jsonl", Self::shard_name(shard), short(sha256))
    }

    /// Index page `page` of the frozen manifest.
    pub fn manifest_page(&self, page: u64, sha256: &str) -> PathBuf {
        self.manifest_dir().join(Self::page_name(page, sha256))
    }

    /// `shard`'s slice of the frozen manifest.
    pub fn manifest_slice(&self, shard: u64, sha256: &str) -> PathBuf {
        self.manifest_dir().join(Self::slice_name(shard, sha256))
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
