//! The journal of a shard in progress: finished items are appended and fsynced as they
//! finish, and the item about to start is recorded before it starts, so a crash is attributed
//! to it and a kill loses at most the item in flight.
//!
//! A result is written to the file before the next item starts (a killed worker process
//! loses nothing the kernel has); its fsync runs in a background thread while the next item
//! converts (group commit: appends made during a flush are covered by the next one), so the
//! disk flush is off the per-item path. A failed background fsync is reported at the next
//! append, and [`Journal::sync`] waits for every flush.

use crate::error::{Result, WorkerError};
use crate::frame::{self, ReadFrame, Record};
use sparc3d_schema::{ErrorClass, ItemStatus, ShardRow};
use std::collections::{BTreeMap, HashMap};
use std::fs::{File, OpenOptions};
use std::io::{BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

/// What the journal says about a finished item (its row stays on disk).
#[derive(Debug, Clone, PartialEq)]
pub struct DoneItem {
    /// Outcome.
    pub status: ItemStatus,
    /// Error class when failed.
    pub class: Option<ErrorClass>,
    /// Seconds the item took.
    pub total_s: f64,
    /// Byte offset of its frame in the journal.
    pub offset: u64,
    /// Unix time it finished.
    pub at: f64,
}

/// Attempts of an unfinished item.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Attempts {
    /// Times it was started.
    pub started: u32,
    /// Times it died with a crash-class failure (observed by the supervisor).
    pub crashes: u32,
    /// Times it was stopped on purpose.
    pub aborted: u32,
    /// The last crash: class and message.
    pub last_crash: Option<(ErrorClass, String)>,
}

impl Attempts {
    /// Starts that ended with neither a result, a crash nor an abort: the worker itself was
    /// killed while the item ran.
    pub fn interrupted(&self) -> u32 {
        self.started.saturating_sub(self.crashes + self.aborted)
    }
}

/// The replayed content of a journal.
#[derive(Debug, Clone, Default)]
pub struct JournalState {
    /// Shard and fingerprint from the header.
    pub header: Option<(u64, String)>,
    /// Finished items by index.
    pub done: BTreeMap<u64, DoneItem>,
    /// Attempts of items not finished.
    pub attempts: HashMap<u64, Attempts>,
    /// The item started last and not finished, with its start time.
    pub in_flight: Option<(u64, f64)>,
    /// Unix time of the first record.
    pub created_at: Option<f64>,
    /// Bytes of valid frames.
    pub valid_len: u64,
    /// Whether the journal ended in a torn or corrupt frame.
    pub torn: bool,
}

impl JournalState {
    fn apply(&mut self, record: &Record, offset: u64) {
        match record {
            Record::Header {
                shard,
                fingerprint,
                created_at,
            } => {
                self.header = Some((*shard, fingerprint.clone()));
                self.created_at = Some(*created_at);
            }
            Record::Start { index, at, .. } => {
                self.attempts.entry(*index).or_default().started += 1;
                self.in_flight = Some((*index, *at));
            }
            Record::Done { row, at } => {
                self.attempts.remove(&row.item_index);
                if self.in_flight.map(|(i, _)| i) == Some(row.item_index) {
                    self.in_flight = None;
                }
                self.done.insert(
                    row.item_index,
                    DoneItem {
                        status: row.status,
                        class: row.error_class,
                        total_s: row.timings.total_s,
                        offset,
                        at: *at,
                    },
                );
            }
            Record::Crash {
                index,
                class,
                message,
                ..
            } => {
                let a = self.attempts.entry(*index).or_default();
                a.crashes += 1;
                a.last_crash = Some((*class, message.clone()));
                self.in_flight = None;
            }
            Record::Abort { index, .. } => {
                self.attempts.entry(*index).or_default().aborted += 1;
                self.in_flight = None;
            }
        }
    }
}

/// Replays a journal without modifying it (safe while a worker appends to it).
pub fn replay(path: &Path) -> Result<JournalState> {
    let f = File::open(path).map_err(|e| WorkerError::io("reading journal", path, e))?;
    let mut r = BufReader::new(f);
    let mut state = JournalState::default();
    loop {
        match frame::read(&mut r).map_err(|e| WorkerError::io("reading journal", path, e))? {
            ReadFrame::Record(rec, len) => {
                state.apply(&rec, state.valid_len);
                state.valid_len += len;
            }
            ReadFrame::End => break,
            ReadFrame::Torn | ReadFrame::Corrupt(_) => {
                state.torn = true;
                break;
            }
        }
    }
    Ok(state)
}

/// An open journal, appended to by the one worker holding the shard's lease.
#[derive(Debug)]
pub struct Journal {
    path: PathBuf,
    file: File,
    syncer: Syncer,
    /// What the journal holds.
    pub state: JournalState,
}

/// Progress of the background fsyncs of one file.
#[derive(Debug, Default)]
struct SyncState {
    /// Flushes asked for so far.
    requested: u64,
    /// Flushes done (a flush started after request k covers every request up to k).
    synced: u64,
    /// The first failed flush, until reported.
    error: Option<std::io::Error>,
    /// Set when the journal closes: finish the pending flush, then stop.
    closing: bool,
}

/// A thread that fsyncs a file whenever asked, coalescing requests made during a flush.
#[derive(Debug)]
struct Syncer {
    shared: Arc<(Mutex<SyncState>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl Syncer {
    fn start(file: File) -> Self {
        let shared = Arc::new((Mutex::new(SyncState::default()), Condvar::new()));
        let worker = Arc::clone(&shared);
        let thread = std::thread::spawn(move || {
            let (lock, cvar) = &*worker;
            let Ok(mut st) = lock.lock() else { return };
            loop {
                while st.synced == st.requested && !st.closing {
                    st = match cvar.wait(st) {
                        Ok(st) => st,
                        Err(_) => return,
                    };
                }
                if st.synced == st.requested {
                    return;
                }
                let target = st.requested;
                drop(st);
                let result = file.sync_data();
                st = match lock.lock() {
                    Ok(st) => st,
                    Err(_) => return,
                };
                st.synced = target;
                if let Err(e) = result {
                    st.error.get_or_insert(e);
                }
                cvar.notify_all();
            }
        });
        Self {
            shared,
            thread: Some(thread),
        }
    }

    /// Asks for a flush of everything written so far; returns at once.
    fn request(&self) {
        let (lock, cvar) = &*self.shared;
        if let Ok(mut st) = lock.lock() {
            st.requested += 1;
            cvar.notify_all();
        }
    }

    /// The error of a failed flush, if one failed since the last call.
    fn take_error(&self) -> Option<std::io::Error> {
        let (lock, _) = &*self.shared;
        match lock.lock() {
            Ok(mut st) => st.error.take(),
            Err(_) => Some(std::io::Error::other("journal sync thread panicked")),
        }
    }

    /// Flushes everything written so far and waits for it.
    fn flush(&self) -> std::io::Result<()> {
        let (lock, cvar) = &*self.shared;
        let poisoned = || std::io::Error::other("journal sync thread panicked");
        let mut st = lock.lock().map_err(|_| poisoned())?;
        st.requested += 1;
        let target = st.requested;
        cvar.notify_all();
        while st.synced < target {
            st = cvar.wait(st).map_err(|_| poisoned())?;
        }
        st.error.take().map_or(Ok(()), Err)
    }
}

impl Drop for Syncer {
    fn drop(&mut self) {
        let (lock, cvar) = &*self.shared;
        if let Ok(mut st) = lock.lock() {
            st.closing = true;
            cvar.notify_all();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Journal {
    /// Opens (or creates) the journal of `shard`, drops a torn tail left by a kill, and
    /// refuses a journal written with another config.
    pub fn open(path: &Path, shard: u64, fingerprint: &str) -> Result<Self> {
        let exists = path.exists();
        let state = if exists {
            replay(path)?
        } else {
            JournalState::default()
        };
        if let Some((_, found)) = &state.header {
            if found != fingerprint {
                return Err(WorkerError::ConfigDrift {
                    what: format!("journal {}", path.display()),
                    found: found.clone(),
                    expected: fingerprint.to_string(),
                });
            }
        }
        let mut file = OpenOptions::new()
            .create(true)
            .read(true)
            .write(true)
            .truncate(false)
            .open(path)
            .map_err(|e| WorkerError::io("opening journal", path, e))?;
        if state.torn || state.header.is_none() {
            file.set_len(state.valid_len)
                .map_err(|e| WorkerError::io("truncating torn journal", path, e))?;
        }
        file.seek(SeekFrom::Start(state.valid_len))
            .map_err(|e| WorkerError::io("opening journal", path, e))?;
        let sync_handle = file
            .try_clone()
            .map_err(|e| WorkerError::io("opening journal", path, e))?;
        let mut journal = Self {
            path: path.to_path_buf(),
            file,
            syncer: Syncer::start(sync_handle),
            state,
        };
        journal.state.torn = false;
        if journal.state.header.is_none() {
            journal.append(&Record::Header {
                shard,
                fingerprint: fingerprint.to_string(),
                created_at: crate::now(),
            })?;
            journal.sync()?;
            if let Some(dir) = path.parent() {
                crate::fsutil::sync_dir(dir)?;
            }
        }
        Ok(journal)
    }

    /// Appends a record and has it fsynced in the background; reports an earlier background
    /// fsync that failed.
    pub fn append(&mut self, record: &Record) -> Result<()> {
        if let Some(e) = self.syncer.take_error() {
            return Err(WorkerError::io("syncing journal", &self.path, e));
        }
        let bytes = frame::encode(record).map_err(|e| WorkerError::BadFile {
            path: self.path.clone(),
            reason: format!("encoding a record: {e}"),
        })?;
        let offset = self.state.valid_len;
        if let Err(e) = self.file.write_all(&bytes) {
            // Leave no half record behind: the next open would drop it anyway.
            let _ = self.file.set_len(offset);
            let _ = self.file.seek(SeekFrom::Start(offset));
            return Err(WorkerError::io("appending to journal", &self.path, e));
        }
        // Results are fsynced; a start mark only needs to survive the death of this process
        // (the kernel keeps it), so it asks for no flush.
        if !matches!(record, Record::Start { .. }) {
            self.syncer.request();
        }
        self.state.apply(record, offset);
        self.state.valid_len += bytes.len() as u64;
        Ok(())
    }

    /// Waits until everything appended so far is on disk.
    pub fn sync(&mut self) -> Result<()> {
        self.syncer
            .flush()
            .map_err(|e| WorkerError::io("syncing journal", &self.path, e))
    }

    /// Reads back the row of a finished item.
    pub fn read_row(&self, item: &DoneItem) -> Result<ShardRow> {
        read_row_at(&self.path, item.offset)
    }

    /// The journal's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Reads the row in the `Done` frame at `offset` of a journal.
pub fn read_row_at(path: &Path, offset: u64) -> Result<ShardRow> {
    let mut f = File::open(path).map_err(|e| WorkerError::io("reading journal", path, e))?;
    f.seek(SeekFrom::Start(offset))
        .map_err(|e| WorkerError::io("reading journal", path, e))?;
    let mut r = BufReader::new(f);
    match frame::read(&mut r).map_err(|e| WorkerError::io("reading journal", path, e))? {
        ReadFrame::Record(Record::Done { row, .. }, _) => Ok(*row),
        other => Err(WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("no finished item at offset {offset}: {other:?}"),
        }),
    }
}

/// Writes a fresh journal holding `rows` as finished items (used to retry failed items of a
/// finished shard), atomically.
pub fn write_with_rows(
    path: &Path,
    shard: u64,
    fingerprint: &str,
    rows: &[ShardRow],
) -> Result<()> {
    let mut bytes = Vec::new();
    let enc = |r: &Record| {
        frame::encode(r).map_err(|e| WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("encoding a record: {e}"),
        })
    };
    bytes.extend(enc(&Record::Header {
        shard,
        fingerprint: fingerprint.to_string(),
        created_at: crate::now(),
    })?);
    for row in rows {
        bytes.extend(enc(&Record::Done {
            row: Box::new(row.clone()),
            at: crate::now(),
        })?);
    }
    crate::fsutil::write_atomic(path, &bytes, "writing journal")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn journal_survives_a_torn_tail_and_refuses_drift() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("j");
        let mut j = Journal::open(&path, 0, "fp")?;
        j.append(&Record::Start {
            index: 0,
            attempt: 1,
            at: 1.0,
        })?;
        let row = ShardRow::failed(0, "a", "/a", 8, ErrorClass::ParseError, "bad".into());
        j.append(&Record::Done {
            row: Box::new(row.clone()),
            at: 2.0,
        })?;
        j.append(&Record::Start {
            index: 1,
            attempt: 1,
            at: 3.0,
        })?;
        drop(j);
        // A torn write at the end.
        let mut f = OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| WorkerError::io("t", &path, e))?;
        f.write_all(b"SPF1\x10\x00")
            .map_err(|e| WorkerError::io("t", &path, e))?;
        drop(f);
        let j = Journal::open(&path, 0, "fp")?;
        assert_eq!(j.state.done.len(), 1);
        assert_eq!(j.state.attempts[&1].interrupted(), 1);
        assert_eq!(j.state.in_flight.map(|x| x.0), Some(1));
        let back = j.read_row(&j.state.done[&0])?;
        assert_eq!(back, row);
        drop(j);
        assert!(matches!(
            Journal::open(&path, 0, "other"),
            Err(WorkerError::ConfigDrift { .. })
        ));
        Ok(())
    }

    /// The counts the shard loop decides retries and give-ups by: a crash and an abort end
    /// an attempt, a start with neither is a killed worker, a result clears the item.
    #[test]
    fn replay_counts_crashes_aborts_and_interrupted_starts() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let path = dir.path().join("j");
        let mut j = Journal::open(&path, 3, "fp")?;
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
        let row = ShardRow::failed(1, "b", "/b", 8, ErrorClass::EmptyMesh, "empty".into());
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
        assert_eq!(state.done[&1].class, Some(ErrorClass::EmptyMesh));
        assert_eq!(
            state.in_flight, None,
            "item 1 finished after item 0's start"
        );
        assert!(!state.torn);
        Ok(())
    }
}
