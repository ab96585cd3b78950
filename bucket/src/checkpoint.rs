//! Checkpoints: a worker's progress on a shard, kept in the bucket so that a worker killed
//! with its machine (a preempted pod) loses little. The worker journals each item locally as
//! on disk; after an item, once [`Checkpoints::every`] has passed since the last checkpoint,
//! the journal's bytes written since then go up as one object of their own
//! (`state/part-NNNNN.journals/<writer>.<seq>.journal`, a journal file by itself: a header,
//! then whole item histories), created only if absent, after a renewal of the lease. The next
//! holder reads every checkpoint of the shard as a journal of an earlier holder, brought into
//! its copy of the job by `pull_checkpoints` (as `status` brings them into its view).
//!
//! Why by time, not by count: the cost of a checkpoint is one PUT of the rows finished since
//! the last, so a time bound caps both what a kill loses (the items of the last interval and
//! the one in flight) and the requests per hour whatever an item takes: at the default 30 s a
//! worker makes at most 120 checkpoint PUTs an hour, and each row is uploaded once in a
//! checkpoint and once in the shard.

use crate::keys;
use crate::lease::BucketLease;
use crate::listing::JobListing;
use anyhow::Context;
use sparc3d_schema::JobLayout;
use sparc3d_sources::list::Listed;
use sparc3d_sources::objects::{Prefix, WriteMode, Written};
use sparc3d_workers::journal::record::{self, ReadFrame, Record};
use sparc3d_workers::journal::{self, Journal};
use sparc3d_workers::Job;
use sparc3d_workers::WorkerError;
use std::collections::BTreeSet;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The default time between checkpoints.
pub const DEFAULT_EVERY: Duration = Duration::from_secs(30);

/// The checkpoints of one holder on one shard.
pub struct Checkpoints {
    prefix: Prefix<'static>,
    shard: u64,
    writer: String,
    lease: Arc<BucketLease>,
    /// Time between checkpoints.
    pub every: Duration,
    last: Instant,
    uploaded: u64,
    seq: u32,
    /// The holder's journal file, once an item was checkpointed or offered.
    journal: Option<PathBuf>,
}

impl Checkpoints {
    /// No checkpoint yet of `writer` on `shard`, fenced by `lease`.
    pub fn new(
        prefix: &Prefix<'static>,
        shard: u64,
        writer: &str,
        lease: Arc<BucketLease>,
        every: Duration,
    ) -> Self {
        Self {
            prefix: prefix.clone(),
            shard,
            writer: writer.to_string(),
            lease,
            every,
            last: Instant::now(),
            uploaded: 0,
            seq: 0,
            journal: None,
        }
    }

    /// Checkpoints once `every` has passed since the last one (or always with `force`), if
    /// the journal grew.
    pub fn after_item(&mut self, journal: &Journal, force: bool) -> Result<(), WorkerError> {
        self.journal = Some(journal.path().to_path_buf());
        self.upload(journal.path().to_path_buf(), journal.len(), force)
    }

    /// A last checkpoint of everything the holder's journal holds (when the worker stops
    /// or fails before the shard is finished).
    pub fn last(&mut self) -> Result<(), WorkerError> {
        let Some(path) = self.journal.clone() else {
            return Ok(());
        };
        let len = std::fs::metadata(&path)
            .map_err(|e| WorkerError::io("reading journal for a checkpoint", &path, e))?
            .len();
        self.upload(path, len, true)
    }

    fn upload(&mut self, path: PathBuf, len: u64, force: bool) -> Result<(), WorkerError> {
        if len <= self.uploaded || (!force && self.last.elapsed() < self.every) {
            return Ok(());
        }
        let bytes = self.segment(path, len)?;
        let key = keys::checkpoint(self.shard, &self.writer, self.seq);
        let url = self.prefix.url(&key).to_string();
        self.lease.confirm().map_err(|why| WorkerError::LeaseLost {
            shard: self.shard,
            lease: PathBuf::from(self.prefix.url(&keys::lease(self.shard)).to_string()),
            why,
        })?;
        match self.prefix.put(&key, bytes, WriteMode::Create) {
            Ok(Written::Done(_)) => {}
            Ok(Written::Refused) => {
                return Err(WorkerError::Remote(format!(
                    "{url}: a checkpoint of this name exists already (two workers with one \
                     name?)"
                )))
            }
            Err(e) => return Err(WorkerError::Remote(format!("uploading checkpoint: {e}"))),
        }
        self.seq += 1;
        self.uploaded = len;
        self.last = Instant::now();
        Ok(())
    }

    /// The journal's bytes from the last checkpoint to `len`, as a journal of their own: the
    /// first checkpoint has the file's header; later ones get a copy of it.
    fn segment(&self, path: PathBuf, len: u64) -> Result<Vec<u8>, WorkerError> {
        let io = |e: std::io::Error| WorkerError::io("reading journal for a checkpoint", &path, e);
        let mut file = std::fs::File::open(&path).map_err(io)?;
        let mut out = Vec::new();
        if self.uploaded > 0 {
            let header = match record::read(&mut BufReader::new(&mut file)).map_err(io)? {
                ReadFrame::Record(h @ Record::Header { .. }, _) => h,
                other => {
                    return Err(WorkerError::BadFile {
                        path: path.clone(),
                        reason: format!("no header at the start: {other:?}"),
                    })
                }
            };
            out = record::encode(&header).map_err(|e| WorkerError::BadFile {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        }
        file.seek(SeekFrom::Start(self.uploaded)).map_err(io)?;
        let start = out.len();
        out.resize(start + (len - self.uploaded) as usize, 0);
        file.read_exact(&mut out[start..]).map_err(io)?;
        Ok(out)
    }
}

/// Makes the scratch copy's journals of `shard` the shard's checkpoints in the bucket: what
/// the earlier holders finished, as journals of earlier holders. A checkpoint is written once
/// under a name of its own and never changed, so one already here with its size is kept; any
/// other journal here goes.
pub(crate) fn pull_checkpoints(prefix: &Prefix<'_>, job: &Job, shard: u64) -> anyhow::Result<()> {
    let found = prefix
        .list(&keys::journals(shard))
        .with_context(|| format!("listing the checkpoints of shard {shard}"))?;
    let wanted: Vec<(String, Listed)> = found
        .into_iter()
        .map(|l| (prefix.relative_key(&l), l))
        .filter(|(key, _)| key.ends_with(".journal"))
        .collect();
    for (key, local) in keep_only(job, shard, &wanted)? {
        download(prefix, &key, &local)?;
    }
    Ok(())
}

/// [`pull_checkpoints`] for every shard at once from one listing of the job (`status`): the
/// local journals of each shard that `unfinished` says is not done become the checkpoints
/// `listing` shows (only the new ones downloaded, [`crate::parallel::IN_FLIGHT`] at a time);
/// those of the other shards go.
pub(crate) fn sync_checkpoints(
    prefix: &Prefix<'_>,
    job: &Job,
    listing: &JobListing,
    unfinished: &dyn Fn(&u64) -> bool,
) -> anyhow::Result<()> {
    let mut shards = local_journal_shards(&job.layout)?;
    shards.extend(listing.journal_shards());
    let mut downloads = Vec::new();
    for shard in shards.into_iter().filter(|s| *s < job.file.shards) {
        let wanted = if unfinished(&shard) {
            listing.journals(shard)
        } else {
            &[]
        };
        downloads.extend(keep_only(job, shard, wanted)?);
    }
    crate::parallel::each(&downloads, crate::parallel::IN_FLIGHT, |(key, local)| {
        download(prefix, key, local)
    })?;
    Ok(())
}

/// The shards whose journals folder is in the local copy.
fn local_journal_shards(layout: &JobLayout) -> anyhow::Result<BTreeSet<u64>> {
    let dir = layout.state_dir();
    let entries = match std::fs::read_dir(&dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(BTreeSet::new()),
        Err(e) => return Err(e).with_context(|| format!("listing {}", dir.display())),
    };
    let mut shards = BTreeSet::new();
    for entry in entries {
        let entry = entry.with_context(|| format!("listing {}", dir.display()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(shard) = keys::shard_of(&name).filter(|_| name.ends_with(".journals")) {
            shards.insert(shard);
        }
    }
    Ok(shards)
}

/// Removes `shard`'s local journals that are not among `wanted` (by name and size); the
/// checkpoints of `wanted` not here yet, as (key, local path) to download.
fn keep_only(
    job: &Job,
    shard: u64,
    wanted: &[(String, Listed)],
) -> anyhow::Result<Vec<(String, PathBuf)>> {
    let layout = &job.layout;
    let name_of = |key: &str| key.rsplit('/').next().unwrap_or_default().to_string();
    for path in journal::set::paths(layout, shard)? {
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let size = std::fs::metadata(&path).map(|m| m.len()).ok();
        let keep = wanted
            .iter()
            .any(|(key, l)| Some(name_of(key)) == name && Some(l.size) == size);
        if !keep {
            std::fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
        }
    }
    let dir = layout.journals_dir(shard);
    if wanted.is_empty() {
        let _ = std::fs::remove_dir(&dir);
        return Ok(Vec::new());
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(wanted
        .iter()
        .map(|(key, _)| (key.clone(), dir.join(name_of(key))))
        .filter(|(_, local)| !local.exists())
        .collect())
}

fn download(prefix: &Prefix<'_>, key: &str, local: &Path) -> anyhow::Result<()> {
    prefix
        .download(key, local)
        .with_context(|| format!("fetching checkpoint {key}"))?;
    Ok(())
}
