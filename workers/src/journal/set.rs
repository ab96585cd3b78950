//! The journals of one shard, read together. Every lease holder writes a file of its own
//! (`state/part-NNNNN.journals/<holder>.journal`); a shard started by an earlier build has its
//! single `state/part-NNNNN.journal`, which is read like any other and never written. What
//! they say together is their states merged oldest first ([`JournalState::absorb`]): an item
//! finished in several (converted again by a holder that lost its lease) counts once, with
//! the latest row.
//!
//! A new holder reads them once, when it takes the shard; what a stopped former holder
//! appends to its own file afterwards is never read by it, and is at worst a second row of an
//! item for a later holder to choose from.

use super::state::{replay, JournalState};
use crate::error::{Result, WorkerError};
use crate::journal::record::{self, Record};
use sparc3d_schema::{JobLayout, ShardRow};
use std::path::{Path, PathBuf};

/// The journal files of `shard`: the single one of an earlier build if there is one, then
/// every holder's, by name.
pub fn paths(layout: &JobLayout, shard: u64) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let legacy = layout.journal(shard);
    if legacy.symlink_metadata().is_ok() {
        out.push(legacy);
    }
    let dir = layout.journals_dir(shard);
    let entries = match std::fs::read_dir(&dir) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(out),
        Err(e) => return Err(WorkerError::io("listing journals", &dir, e)),
    };
    let mut holders = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| WorkerError::io("listing journals", &dir, e))?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        // Temporary files of an atomic write start with a dot.
        if name.ends_with(".journal") && !name.starts_with('.') {
            holders.push(entry.path());
        }
    }
    holders.sort();
    out.extend(holders);
    Ok(out)
}

/// Whether `shard` has any journal left (or its folder of journals).
pub fn exists(layout: &JobLayout, shard: u64) -> bool {
    layout.journal(shard).symlink_metadata().is_ok()
        || layout.journals_dir(shard).symlink_metadata().is_ok()
}

/// What the journals of `shard` say together, oldest first (by their headers' creation
/// times). A journal without a header (created, then killed) says nothing. With
/// `fingerprint`, a journal written with another config is an error.
pub fn read(layout: &JobLayout, shard: u64, fingerprint: Option<&str>) -> Result<JournalState> {
    let mut states = Vec::new();
    for path in paths(layout, shard)? {
        let state = match replay(&path) {
            Ok(s) => s,
            // Removed since it was listed: its shard was finished meanwhile.
            Err(WorkerError::Io { source, .. })
                if source.kind() == std::io::ErrorKind::NotFound =>
            {
                continue
            }
            Err(e) => return Err(e),
        };
        let Some((_, found)) = &state.header else {
            continue;
        };
        if let Some(expected) = fingerprint.filter(|fp| found != fp) {
            return Err(WorkerError::ConfigDrift {
                what: format!("journal {}", path.display()),
                found: found.clone(),
                expected: expected.to_string(),
            });
        }
        states.push((state.created_at.unwrap_or(0.0), path, state));
    }
    states.sort_by(|a, b| a.0.total_cmp(&b.0).then_with(|| a.1.cmp(&b.1)));
    let mut all = JournalState::default();
    for (_, _, state) in states {
        all.absorb(state);
    }
    Ok(all)
}

/// Removes every journal of `shard` and their folder (once its shard is written). A file a
/// stopped former holder creates meanwhile keeps the folder; `clear_leftovers` removes it
/// later.
pub fn remove_all(layout: &JobLayout, shard: u64) -> Result<()> {
    for path in paths(layout, shard)? {
        match std::fs::remove_file(&path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(WorkerError::io("removing journal", &path, e)),
        }
    }
    let dir = layout.journals_dir(shard);
    match std::fs::remove_dir(&dir) {
        Ok(()) => Ok(()),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::DirectoryNotEmpty
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(WorkerError::io("removing journals folder", &dir, e)),
    }
}

/// Replaces the journals of `shard` by one holding `rows` as finished items (used to retry
/// failed items): the new journal is written atomically first, then the others go. A kill in
/// between leaves both; they then say what the old ones said, and the retry can be repeated.
pub fn replace_with_rows(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    rows: &[ShardRow],
) -> Result<()> {
    let stamp = crate::clock::since_epoch().as_nanos();
    let name = format!("retry-{stamp}-{}", std::process::id());
    let path = layout.holder_journal(shard, &name);
    let bytes = with_rows(&path, shard, fingerprint, rows)?;
    crate::fsutil::create_dir(&layout.journals_dir(shard))?;
    crate::fsutil::write_atomic(&path, &bytes, "writing journal")?;
    for old in paths(layout, shard)?.into_iter().filter(|p| *p != path) {
        match std::fs::remove_file(&old) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(WorkerError::io("removing journal", &old, e)),
        }
    }
    crate::fsutil::sync_dir(&layout.state_dir())
}

/// The bytes of a journal holding `rows` as finished items (`path` names it in errors).
pub fn with_rows(path: &Path, shard: u64, fingerprint: &str, rows: &[ShardRow]) -> Result<Vec<u8>> {
    let enc = |r: &Record| {
        record::encode(r).map_err(|e| WorkerError::BadFile {
            path: path.to_path_buf(),
            reason: format!("encoding a record: {e}"),
        })
    };
    let mut bytes = enc(&Record::Header {
        shard,
        fingerprint: fingerprint.to_string(),
        created_at: crate::clock::now(),
    })?;
    for row in rows {
        bytes.extend(enc(&Record::Done {
            row: Box::new(row.clone()),
            at: crate::clock::now(),
        })?);
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::journal::Journal;
    use sparc3d_schema::ErrorClass;
    use std::io::Write;

    fn io(e: std::io::Error) -> WorkerError {
        WorkerError::io("test", "/tmp", e)
    }

    fn failed(index: u64, message: &str) -> ShardRow {
        ShardRow::failed(
            index,
            &format!("i{index}"),
            "/m",
            8,
            ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
            message.into(),
        )
    }

    fn start(index: u64) -> Record {
        Record::Start {
            index,
            attempt: 1,
            at: crate::clock::now(),
        }
    }

    fn done(row: &ShardRow) -> Record {
        Record::Done {
            row: Box::new(row.clone()),
            at: crate::clock::now(),
        }
    }

    /// Issue 32, item 4, on the journals alone: holder A is stopped with item 1 in flight; B
    /// takes over, reading A's journal, and journals items 1 and 2 in a file of its own. A,
    /// continued, appends item 1's result: B's file is untouched, B reads back its own rows,
    /// and a later reader counts item 1 once, with B's row.
    #[test]
    fn a_former_holders_late_append_cannot_touch_the_new_holders_journal() -> Result<()> {
        let dir = tempfile::tempdir().map_err(io)?;
        let layout = JobLayout::new(dir.path());
        let mut a = Journal::create(
            &layout.holder_journal(0, "a"),
            0,
            "fp",
            JournalState::default(),
        )?;
        a.append(&start(0))?;
        a.append(&done(&failed(0, "by a")))?;
        a.append(&start(1))?;
        let earlier = read(&layout, 0, Some("fp"))?;
        assert_eq!(earlier.in_flight.keys().next(), Some(&1));
        let mut b = Journal::create(&layout.holder_journal(0, "b"), 0, "fp", earlier)?;
        for (i, msg) in [(1, "by b"), (2, "by b")] {
            b.append(&start(i))?;
            b.append(&done(&failed(i, msg)))?;
        }
        b.sync()?;
        let b_bytes = std::fs::read(b.path()).map_err(io)?;
        // A is continued: its result of item 1 and more.
        a.append(&done(&failed(1, "by a, late")))?;
        a.append(&start(2))?;
        a.sync()?;
        assert_eq!(std::fs::read(b.path()).map_err(io)?, b_bytes);
        let rows: Vec<ShardRow> = b
            .state
            .done
            .values()
            .map(|d| b.read_row(d))
            .collect::<Result<_>>()?;
        let messages: Vec<_> = rows.iter().map(|r| r.error_message.clone()).collect();
        let expected = ["by a", "by b", "by b"].map(|m| Some(m.to_string()));
        assert_eq!(messages, expected);
        let later = read(&layout, 0, Some("fp"))?;
        assert_eq!(later.done.len(), 3);
        assert_eq!(
            later.done[&1].journal.as_ref(),
            b.path(),
            "the latest row wins"
        );
        assert!(later.attempts.is_empty() && later.in_flight.is_empty());
        Ok(())
    }

    /// A torn tail (a kill during a write) ends what a journal says; a journal of another
    /// config is refused; a single journal of an earlier build is read like a holder's.
    #[test]
    fn torn_tails_are_dropped_other_configs_refused_and_old_journals_read() -> Result<()> {
        let dir = tempfile::tempdir().map_err(io)?;
        let layout = JobLayout::new(dir.path());
        std::fs::create_dir_all(layout.state_dir()).map_err(io)?;
        let mut old = Journal::create(&layout.journal(0), 0, "fp", JournalState::default())?;
        old.append(&start(0))?;
        old.append(&done(&failed(0, "old")))?;
        old.append(&start(1))?;
        drop(old);
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(layout.journal(0))
            .map_err(io)?;
        f.write_all(b"SPF1\x10\x00").map_err(io)?;
        let state = read(&layout, 0, Some("fp"))?;
        assert_eq!(state.done.len(), 1);
        assert!(state.torn);
        assert_eq!(state.attempts[&1].interrupted(), 1);
        assert_eq!(
            crate::journal::read_row_at(&state.done[&0].journal, state.done[&0].offset)?,
            failed(0, "old")
        );
        assert!(matches!(
            read(&layout, 0, Some("other")),
            Err(WorkerError::ConfigDrift { .. })
        ));
        replace_with_rows(&layout, 0, "fp", &[failed(3, "kept")])?;
        assert_eq!(paths(&layout, 0)?.len(), 1, "the old journal is replaced");
        assert_eq!(
            read(&layout, 0, None)?.done.keys().collect::<Vec<_>>(),
            [&3]
        );
        remove_all(&layout, 0)?;
        assert!(!exists(&layout, 0));
        Ok(())
    }
}
