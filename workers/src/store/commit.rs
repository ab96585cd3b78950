//! Putting a written shard in place: its file under the shard's name, then its completion
//! record, so that no worker replaces a shard another one finished.
//!
//! Both names are taken with a hard link from a temporary file of the writer's own, which
//! fails when the name exists, never with a rename over it. A writer that finds a finished
//! shard there (record and file matching) leaves it and reports it finished elsewhere (the
//! first complete commit wins; every commit holds every item of the shard once). A file there
//! without a matching record was left by a writer stopped or killed between the two steps
//! (its rows are still in the journals, which go only after the record): it is taken out of
//! the way, a damaged one moved aside like any damaged shard. The record is written only
//! while the file under the shard's name is the writer's own inode, so it always describes
//! the file it stands beside, unless the writer is stopped between that check and the link
//! and another writer replaces the file meanwhile; the next check then finds a record that
//! does not match, moves both aside and converts the shard again (docs/RELIABILITY.md,
//! "Fencing a holder that lost its lease").

use super::state::{completion, quarantine, Check, Completion};
use crate::error::{Result, WorkerError};
use crate::fsutil::{file_stamp, link_no_replace, sync_dir};
use sparc3d_schema::{CompletionRecord, JobLayout};
use std::fs::{File, Metadata};
use std::io::Write;
use std::os::unix::fs::MetadataExt;
use std::path::Path;

/// Times a shard's name is tried before giving up when files keep appearing there.
const PLACE_TRIES: usize = 4;

/// How a commit ended, on disk or in a bucket.
#[derive(Debug, Clone, PartialEq)]
pub enum Committed {
    /// This writer's shard is the one its record names (in place on disk, or uploaded).
    Done(CompletionRecord),
    /// Another worker's finished shard was there already (its record); this one was
    /// discarded.
    FinishedElsewhere(CompletionRecord),
}

/// Commits the shard file written and fsynced at `tmp` (still open as `file`) with its
/// `record`, whose size, stamp and finish time are filled in here. `writer` names the
/// writer's temporary files. `tmp` is gone afterwards, whatever happened.
pub fn commit(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    tmp: &Path,
    file: &File,
    record: CompletionRecord,
    writer: &str,
) -> Result<Committed> {
    let placed = place(layout, shard, fingerprint, tmp);
    let _ = std::fs::remove_file(tmp);
    if let Some(theirs) = placed? {
        return Ok(Committed::FinishedElsewhere(theirs));
    }
    sync_dir(&layout.shards_dir())?;
    // The stamp of this inode now that its links are final (a link changes its ctime).
    let meta = file
        .metadata()
        .map_err(|e| WorkerError::io("reading shard size", tmp, e))?;
    let record = CompletionRecord {
        bytes: meta.len(),
        stamp: Some(file_stamp(&meta)),
        finished_at: crate::clock::now(),
        ..record
    };
    write_record(layout, shard, fingerprint, &record, &meta, writer)
}

/// Links `tmp` to the shard's name unless a file is there; `Some(record)` when the file
/// there is a finished shard (left alone). A file without a record that matches it is taken
/// out of the way first.
fn place(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    tmp: &Path,
) -> Result<Option<CompletionRecord>> {
    let target = layout.shard_file(shard);
    for _ in 0..PLACE_TRIES {
        if link_no_replace(tmp, &target)
            .map_err(|e| WorkerError::io("placing shard", &target, e))?
        {
            return Ok(None);
        }
        match completion(layout, shard, fingerprint, Check::Quick)? {
            Completion::Done(theirs) => return Ok(Some(*theirs)),
            Completion::Damaged(why) => {
                quarantine(
                    layout,
                    shard,
                    &format!("{why} (found when the shard was about to be written again)"),
                )?;
            }
            Completion::Absent => match std::fs::remove_file(&target) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(WorkerError::io("removing unfinished shard", &target, e)),
            },
        }
    }
    Err(WorkerError::BadFile {
        path: target,
        reason: format!(
            "another file took this name each of the {PLACE_TRIES} times the shard was about \
             to be written (several workers writing it at once?); run again"
        ),
    })
}

/// Whether the file under the shard's name is the inode described by `placed`.
fn still_placed(layout: &JobLayout, shard: u64, placed: &Metadata) -> bool {
    std::fs::metadata(layout.shard_file(shard))
        .is_ok_and(|m| m.ino() == placed.ino() && m.dev() == placed.dev())
}

/// The outcome when this writer's file is no longer under the shard's name: another writer
/// took the name.
fn replaced(layout: &JobLayout, shard: u64, fingerprint: &str) -> Result<Committed> {
    match completion(layout, shard, fingerprint, Check::Quick)? {
        Completion::Done(theirs) => Ok(Committed::FinishedElsewhere(*theirs)),
        _ => Err(WorkerError::BadFile {
            path: layout.shard_file(shard),
            reason: "replaced by another worker's shard file while its completion record was \
                     being written; run again"
                .into(),
        }),
    }
}

/// Writes `record` as the shard's completion record while the shard's file is this writer's
/// (`placed`): to a temporary file, fsynced, then linked; a record already there cannot
/// describe the file just placed (a commit that did not finish) and is replaced.
fn write_record(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    record: &CompletionRecord,
    placed: &Metadata,
    writer: &str,
) -> Result<Committed> {
    let path = layout.completion(shard);
    let tmp = layout.shards_dir().join(format!(
        ".{}.complete.json.tmp-{writer}",
        JobLayout::shard_name(shard)
    ));
    let json = serde_json::to_vec_pretty(record).map_err(|e| WorkerError::BadFile {
        path: path.clone(),
        reason: e.to_string(),
    })?;
    let result = (|| {
        let stage = "writing completion record";
        let mut f = File::create(&tmp).map_err(|e| WorkerError::io(stage, &tmp, e))?;
        f.write_all(&json)
            .and_then(|()| f.sync_all())
            .map_err(|e| WorkerError::io(stage, &tmp, e))?;
        if !still_placed(layout, shard, placed) {
            return replaced(layout, shard, fingerprint);
        }
        if !link_no_replace(&tmp, &path).map_err(|e| WorkerError::io(stage, &path, e))? {
            if !still_placed(layout, shard, placed) {
                return replaced(layout, shard, fingerprint);
            }
            std::fs::rename(&tmp, &path).map_err(|e| WorkerError::io(stage, &path, e))?;
        }
        sync_dir(&layout.shards_dir())?;
        Ok(Committed::Done(record.clone()))
    })();
    let _ = std::fs::remove_file(&tmp);
    result
}
