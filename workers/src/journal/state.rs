//! What a journal says: finished items (where their rows are), attempts of unfinished ones,
//! the item in flight. Built by replaying one journal file ([`replay`]) and by merging the
//! journals of a shard's successive holders, oldest first ([`JournalState::absorb`]).

use crate::error::{Result, WorkerError};
use crate::journal::record::{self, ReadFrame, Record};
use sparc3d_schema::{ErrorClass, ItemStatus};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use std::sync::Arc;

/// What the journal says about a finished item (its row stays on disk).
#[derive(Debug, Clone, PartialEq)]
pub struct DoneItem {
    /// Outcome.
    pub status: ItemStatus,
    /// Error class when failed.
    pub class: Option<ErrorClass>,
    /// Seconds the item took.
    pub total_s: f64,
    /// The journal file that holds its row.
    pub journal: Arc<Path>,
    /// Byte offset of its frame in that file.
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

    /// These attempts followed by `later` ones (of a later journal).
    fn then(&mut self, later: Attempts) {
        self.started += later.started;
        self.crashes += later.crashes;
        self.aborted += later.aborted;
        if later.last_crash.is_some() {
            self.last_crash = later.last_crash;
        }
    }
}

/// The replayed content of a journal, or of all the journals of a shard.
#[derive(Debug, Clone, Default)]
pub struct JournalState {
    /// Shard and fingerprint from the (first) header.
    pub header: Option<(u64, String)>,
    /// Finished items by index.
    pub done: BTreeMap<u64, DoneItem>,
    /// Attempts of items not finished.
    pub attempts: HashMap<u64, Attempts>,
    /// Items started and not finished, with their start times (of the latest journal: one
    /// holder, converting one item at a time or several with lanes).
    pub in_flight: BTreeMap<u64, f64>,
    /// Unix time of the first record.
    pub created_at: Option<f64>,
    /// Bytes of valid frames (of one file; summed over merged ones).
    pub valid_len: u64,
    /// Whether a journal ended in a torn or corrupt frame.
    pub torn: bool,
}

impl JournalState {
    /// Applies one record found at `offset` of the journal file `journal`.
    pub(crate) fn apply(&mut self, record: &Record, journal: &Arc<Path>, offset: u64) {
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
                self.in_flight.insert(*index, *at);
            }
            Record::Done { row, at } => {
                self.attempts.remove(&row.item_index);
                self.in_flight.remove(&row.item_index);
                self.done.insert(
                    row.item_index,
                    DoneItem {
                        status: row.status,
                        class: row.error_class,
                        total_s: row.timings.total_s,
                        journal: journal.clone(),
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
                self.in_flight.remove(index);
            }
            Record::Abort { index, .. } => {
                self.attempts.entry(*index).or_default().aborted += 1;
                self.in_flight.remove(index);
            }
        }
    }

    /// Adds what a later journal of the same shard says: its finished items (a row of an item
    /// finished in both wins over the earlier one: the same item converted twice, e.g. by a
    /// holder that lost its lease), its attempts added to these, its items in flight.
    pub fn absorb(&mut self, later: JournalState) {
        if self.header.is_none() {
            self.header = later.header;
        }
        self.created_at = match (self.created_at, later.created_at) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self.done.extend(later.done);
        for (index, a) in later.attempts {
            self.attempts.entry(index).or_default().then(a);
        }
        self.in_flight = later.in_flight;
        self.valid_len += later.valid_len;
        self.torn |= later.torn;
        let done = &self.done;
        self.attempts.retain(|index, _| !done.contains_key(index));
        self.in_flight.retain(|index, _| !done.contains_key(index));
    }
}

/// Replays a journal file without modifying it (safe while a worker appends to it). A torn or
/// corrupt frame ends it: what follows is not trusted.
pub fn replay(path: &Path) -> Result<JournalState> {
    let f = File::open(path).map_err(|e| WorkerError::io("reading journal", path, e))?;
    let mut r = BufReader::new(f);
    let journal: Arc<Path> = Arc::from(path);
    let mut state = JournalState::default();
    loop {
        match record::read(&mut r).map_err(|e| WorkerError::io("reading journal", path, e))? {
            ReadFrame::Record(rec, len) => {
                state.apply(&rec, &journal, state.valid_len);
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
