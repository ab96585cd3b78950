//! The journal of a shard in progress: finished items are appended and fsynced as they
//! finish, and the item about to start is recorded before it starts, so a crash is attributed
//! to it and a kill loses at most the item in flight.
//!
//! Each lease holder writes a journal file of its own ([`Journal::create`]: created new,
//! never opened by another worker for writing), after reading what the shard's earlier
//! holders journalled ([`set`]). So a holder that lost its lease while stopped and is
//! continued can append at most to its own file, which the new holder never reads again: it
//! cannot overwrite the new holder's records (docs/RELIABILITY.md, "Fencing a holder that
//! lost its lease").
//!
//! A result is written to the file before the next item starts (a killed worker process
//! loses nothing the kernel has); its fsync runs in a background thread while the next item
//! converts (group commit: appends made during a flush are covered by the next one,
//! `syncer`), so the disk flush is off the per-item path. A failed background fsync is
//! reported at the next append, and [`Journal::sync`] waits for every flush.

pub mod record;
pub mod set;
mod state;
mod syncer;

pub use state::{replay, Attempts, DoneItem, JournalState};

use crate::error::{Result, WorkerError};
use record::{ReadFrame, Record};
use sparc3d_schema::ShardRow;
use std::fs::{File, OpenOptions};
use std::io::{BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use syncer::Syncer;

/// This holder's journal of a shard, appended by it alone.
#[derive(Debug)]
pub struct Journal {
    path: PathBuf,
    /// The same path, shared by the [`DoneItem`]s of this file.
    own: Arc<Path>,
    file: File,
    syncer: Syncer,
    /// Bytes written to this file.
    len: u64,
    /// What the shard's journals say: the earlier holders' and this one.
    pub state: JournalState,
}

impl Journal {
    /// Starts a holder's journal of `shard` at `path`, a file no other worker writes: created
    /// new (an existing file is an error), its header fsynced with its folder. `earlier` is
    /// what the shard's earlier journals say ([`set::read`]); [`Journal::state`] starts there.
    pub fn create(
        path: &Path,
        shard: u64,
        fingerprint: &str,
        earlier: JournalState,
    ) -> Result<Self> {
        let dir = path.parent().unwrap_or(Path::new("."));
        crate::fsutil::create_dir(dir)?;
        if let Some(up) = dir.parent() {
            crate::fsutil::sync_dir(up)?;
        }
        let file = OpenOptions::new()
            .create_new(true)
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| WorkerError::io("creating journal", path, e))?;
        let sync_handle = file
            .try_clone()
            .map_err(|e| WorkerError::io("creating journal", path, e))?;
        let mut journal = Self {
            path: path.to_path_buf(),
            own: Arc::from(path),
            file,
            syncer: Syncer::start(sync_handle),
            len: 0,
            state: earlier,
        };
        let created_at = crate::clock::now();
        journal.write_frame(&Record::Header {
            shard,
            fingerprint: fingerprint.to_string(),
            created_at,
        })?;
        journal
            .state
            .header
            .get_or_insert((shard, fingerprint.to_string()));
        journal.state.created_at.get_or_insert(created_at);
        journal.sync()?;
        crate::fsutil::sync_dir(dir)?;
        Ok(journal)
    }

    /// Appends a record and has it fsynced in the background; reports an earlier background
    /// fsync that failed.
    pub fn append(&mut self, record: &Record) -> Result<()> {
        let offset = self.len;
        self.write_frame(record)?;
        self.state.apply(record, &self.own, offset);
        Ok(())
    }

    /// Writes a record's frame at the end of this file.
    fn write_frame(&mut self, record: &Record) -> Result<()> {
        if let Some(e) = self.syncer.take_error() {
            return Err(WorkerError::io("syncing journal", &self.path, e));
        }
        let bytes = record::encode(record).map_err(|e| WorkerError::BadFile {
            path: self.path.clone(),
            reason: format!("encoding a record: {e}"),
        })?;
        let offset = self.len;
        if let Err(e) = self.file.write_all(&bytes) {
            // Leave no half record behind: a reader would stop there anyway.
            let _ = self.file.set_len(offset);
            let _ = self.file.seek(SeekFrom::Start(offset));
            return Err(WorkerError::io("appending to journal", &self.path, e));
        }
        // Results are fsynced; a start mark only needs to survive the death of this process
        // (the kernel keeps it), so it asks for no flush.
        if !matches!(record, Record::Start { .. }) {
            self.syncer.request();
        }
        self.len += bytes.len() as u64;
        self.state.valid_len += bytes.len() as u64;
        Ok(())
    }

    /// Waits until everything appended so far is on disk.
    pub fn sync(&mut self) -> Result<()> {
        self.syncer
            .flush()
            .map_err(|e| WorkerError::io("syncing journal", &self.path, e))
    }

    /// Reports a background flush that failed so far, without waiting for the one running.
    pub fn check(&self) -> Result<()> {
        match self.syncer.take_error() {
            Some(e) => Err(WorkerError::io("syncing journal", &self.path, e)),
            None => Ok(()),
        }
    }

    /// Closes the journal without waiting for its flushes, for a journal whose rows are in a
    /// committed shard now (about to be removed): the flush running finishes in the background.
    pub fn abandon(self) {
        self.syncer.abandon();
    }

    /// Reads back the row of a finished item (from whichever journal holds it).
    pub fn read_row(&self, item: &DoneItem) -> Result<ShardRow> {
        read_row_at(&item.journal, item.offset)
    }

    /// This journal's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Bytes written to this journal's file (every frame whole).
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether nothing was written to the file yet (never, once created: it has a header).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Reads the row in the `Done` frame at `offset` of a journal.
pub fn read_row_at(path: &Path, offset: u64) -> Result<ShardRow> {
    let mut f = File::open(path).map_err(|e| WorkerError::io("reading journal", path, e))?;
    f.seek(SeekFrom::Start(offset))
        .map_err(|e| WorkerError::io("reading journal", path, e))?;
    let mut r = BufReader::new(f);
    match record::read(&mut r).map_err(|e| WorkerError::io("reading journal", path, e))? {
        ReadFrame::Record(Record::Done { row, .. }, _) => Ok(*row),
        other => Err(WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("no finished item at offset {offset}: {other:?}"),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparc3d_schema::ErrorClass;

    /// A journal is its holder's alone: creating one where a file exists fails.
    #[test]
    fn a_journal_file_is_never_opened_twice_for_writing() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("j");
        let j = Journal::create(&path, 0, "fp", JournalState::default())?;
        assert!(matches!(
            Journal::create(&path, 0, "fp", JournalState::default()),
            Err(WorkerError::Io {
                stage: "creating journal",
                ..
            })
        ));
        drop(j);
        Ok(())
    }

    /// The counts the shard loop decides retries and give-ups by: a crash and an abort end
    /// an attempt, a start with neither is a killed worker, a result clears the item.
    #[test]
    fn replay_counts_crashes_aborts_and_interrupted_starts() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("j");
        let mut j = Journal::create(&path, 3, "fp", JournalState::default())?;
        let start = |index, attempt| Record::Start {
            index,
            attempt,
            at: 1.0,
        };
        j.append(&start(0, 1))?;
        j.append(&Record::Crash {
            index: 0,
            class: ErrorClass::Crashed,
            message: "killed by signal 9".into(),
            at: 2.0,
        })?;
        j.append(&start(0, 2))?;
        j.append(&Record::Abort { index: 0, at: 3.0 })?;
        j.append(&start(0, 3))?; // the worker itself was killed here
        j.append(&start(1, 1))?;
        let row = ShardRow::failed(
            1,
            "b",
            "/b",
            8,
            ErrorClass::Geometry(sparcubes::ErrorClass::EmptyMesh),
            "empty".into(),
        );
        j.append(&Record::Done {
            row: Box::new(row),
            at: 4.0,
        })?;
        drop(j);
        let state = replay(&path)?;
        assert_eq!(state.header, Some((3, "fp".to_string())));
        let a = &state.attempts[&0];
        assert_eq!((a.started, a.crashes, a.aborted), (3, 1, 1));
        assert_eq!(a.interrupted(), 1);
        assert_eq!(
            a.last_crash,
            Some((ErrorClass::Crashed, "killed by signal 9".to_string()))
        );
        assert!(!state.attempts.contains_key(&1), "a result clears the item");
        assert_eq!(
            state.done[&1].class,
            Some(ErrorClass::Geometry(sparcubes::ErrorClass::EmptyMesh))
        );
        assert_eq!(
            state.in_flight.keys().collect::<Vec<_>>(),
            vec![&0],
            "item 0's last start has no result (still converting in another lane); item 1 finished"
        );
        assert!(!state.torn);
        Ok(())
    }
}
