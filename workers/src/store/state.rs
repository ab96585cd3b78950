//! Whether a shard is done (a completion record that the shard file matches), damaged (a
//! record the file does not match, or a record that does not parse), running (a live lease)
//! or pending; and moving a damaged shard aside so that it is converted again.
//!
//! A finished shard is trusted only as far as it is checked against its completion record:
//! [`Check::Quick`] compares the size and the file's stamp (modification and change times,
//! inode) and hashes the file only when the stamp differs; [`Check::Full`] always hashes it
//! against the recorded sha256 (docs/RELIABILITY.md).

use crate::error::{Result, WorkerError};
use crate::fsutil::{create_dir, file_sha256, file_stamp, sync_dir};
use crate::lease::{self, LeaseInfo};
use sparc3d_schema::{CompletionRecord, JobLayout};
use std::path::{Path, PathBuf};

/// How thoroughly a finished shard is checked against its completion record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Check {
    /// The size and the recorded stamp; the whole file is hashed only when the stamp differs.
    Quick,
    /// The whole file hashed and compared with the recorded sha256.
    Full,
}

/// What a shard's completion record says, once checked.
#[derive(Debug, Clone, PartialEq)]
pub enum Completion {
    /// No record: the shard is not finished.
    Absent,
    /// The record is valid and the shard file matches it.
    Done(Box<CompletionRecord>),
    /// A record exists but the shard cannot be trusted; the reason. The shard must be moved
    /// aside ([`quarantine`]) and converted again.
    Damaged(String),
}

/// The state of one shard.
// One value per shard, held briefly by the commands that list states: the size of the record
// (which grew by its object's ETag) costs nothing worth a box at every match.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum ShardState {
    /// Finished: its completion record.
    Done(CompletionRecord),
    /// A live worker holds its lease.
    Running(LeaseInfo),
    /// Not finished and not held (it may have a journal of finished items).
    Pending,
    /// Finished once, but its file no longer matches its record (or the record is torn);
    /// not held. The next worker moves it aside and converts it again.
    Damaged(String),
}

/// Checks shard `shard`'s completion record and file. A record with another fingerprint is
/// an error (a config drift, never repaired by itself); everything else that is wrong with a
/// finished shard is [`Completion::Damaged`].
pub fn completion(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    check: Check,
) -> Result<Completion> {
    let path = layout.completion(shard);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Completion::Absent),
        Err(e) => return Err(WorkerError::io("reading", &path, e)),
    };
    let record: CompletionRecord = match serde_json::from_slice(&bytes) {
        Ok(r) => r,
        Err(e) => {
            return Ok(Completion::Damaged(format!(
                "its completion record {} does not parse ({e})",
                path.display()
            )))
        }
    };
    if record.fingerprint != fingerprint {
        return Err(WorkerError::ConfigDrift {
            what: format!("shard {}", layout.shard_file(shard).display()),
            found: record.fingerprint,
            expected: fingerprint.to_string(),
        });
    }
    if record.shard != shard {
        return Ok(Completion::Damaged(format!(
            "its completion record is shard {}'s",
            record.shard
        )));
    }
    Ok(
        match check_file(&layout.shard_file(shard), &record, check)? {
            None => Completion::Done(Box::new(record)),
            Some(why) => Completion::Damaged(why),
        },
    )
}

/// `None` when the shard file `file` matches its completion record (as far as `check`
/// looks), else why not.
pub fn check_file(file: &Path, record: &CompletionRecord, check: Check) -> Result<Option<String>> {
    let meta = match std::fs::metadata(file) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(Some(format!("{} is missing", file.display())))
        }
        Err(e) => return Err(WorkerError::io("reading", file, e)),
    };
    if meta.len() != record.bytes {
        return Ok(Some(format!(
            "{} has {} bytes, its completion record says {}",
            file.display(),
            meta.len(),
            record.bytes
        )));
    }
    if check == Check::Quick && record.stamp == Some(file_stamp(&meta)) {
        return Ok(None);
    }
    let sha = file_sha256(file)?;
    Ok(hash_mismatch(file, &sha, record))
}

/// Why the shard file `file` whose sha256 is `sha` does not match `record`, or `None`.
pub fn hash_mismatch(file: &Path, sha: &str, record: &CompletionRecord) -> Option<String> {
    (sha != record.sha256).then(|| {
        format!(
            "{} has sha256 {sha}, its completion record says {} (the file changed after it \
             was written)",
            file.display(),
            record.sha256
        )
    })
}

/// The state of a shard, its record checked with `check`.
pub fn shard_state(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    check: Check,
) -> Result<ShardState> {
    let damaged = match completion(layout, shard, fingerprint, check)? {
        Completion::Done(r) => return Ok(ShardState::Done(*r)),
        Completion::Damaged(why) => Some(why),
        Completion::Absent => None,
    };
    match lease::read(&layout.lease(shard)) {
        Some(l) if !l.is_stale(crate::clock::now()) => Ok(ShardState::Running(l)),
        _ => Ok(damaged.map_or(ShardState::Pending, ShardState::Damaged)),
    }
}

/// Moves a damaged shard's completion record and file (whichever exist) into
/// `JOB/quarantine/part-NNNNN-<unix time>/`, then writes `reason.txt` there naming why and
/// the files moved, so that the shard counts as not finished and is converted again. Nothing
/// is deleted. The note comes last: a process killed part-way leaves no note that names a
/// file still in `shards/` (a folder without one was interrupted while moving). The caller
/// holds the shard's lease. Returns the folder.
pub fn quarantine(layout: &JobLayout, shard: u64, reason: &str) -> Result<PathBuf> {
    let stamp = crate::clock::since_epoch().as_millis();
    let dir = layout
        .quarantine_dir()
        .join(format!("{}-{stamp}", JobLayout::shard_name(shard)));
    create_dir(&dir)?;
    // The record first: without it the shard is no longer done, whatever happens next.
    let mut moved = Vec::new();
    for from in [layout.completion(shard), layout.shard_file(shard)] {
        let Some(name) = from.file_name() else {
            continue;
        };
        match std::fs::rename(&from, dir.join(name)) {
            Ok(()) => moved.push(name.to_string_lossy().into_owned()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(WorkerError::io("moving a damaged shard aside", &from, e)),
        }
    }
    sync_dir(&layout.shards_dir())?;
    let note = format!(
        "shard {shard}: {reason}\nmoved here from {}: {}\n",
        layout.shards_dir().display(),
        if moved.is_empty() {
            "nothing (neither file was there)".to_string()
        } else {
            moved.join(", ")
        }
    );
    crate::fsutil::write_atomic(
        &dir.join("reason.txt"),
        note.as_bytes(),
        "writing quarantine note",
    )?;
    Ok(dir)
}

/// What [`verify_shard`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum Verified {
    /// Not finished: nothing to verify.
    NotFinished,
    /// The file matches its record; `restamped` when the file had been touched without being
    /// changed (copied, `touch`ed) and its new stamp was recorded, so quick checks stay quick.
    Good {
        /// The record.
        record: Box<CompletionRecord>,
        /// Whether the stamp was re-recorded.
        restamped: bool,
    },
    /// Damaged; moved aside to `moved_to` (`None` when only reported).
    Damaged {
        /// What is wrong.
        reason: String,
        /// Where the record and file went.
        moved_to: Option<PathBuf>,
    },
    /// Needed a change (damaged, or a stamp to re-record) but a live worker holds the lease.
    Busy {
        /// What was found.
        reason: String,
        /// The lease holder.
        owner: String,
    },
}

/// Hashes a finished shard against its completion record ([`Check::Full`]); with `repair`, a
/// damaged shard is moved aside ([`quarantine`]) so that the next `run` converts it again,
/// and a good shard whose stamp changed has its new stamp recorded. Changes are made under
/// the shard's lease; a shard held by a live worker is left alone ([`Verified::Busy`]).
pub fn verify_shard(
    layout: &JobLayout,
    shard: u64,
    fingerprint: &str,
    repair: bool,
) -> Result<Verified> {
    let (reason, restamp) = match completion(layout, shard, fingerprint, Check::Full)? {
        Completion::Absent => return Ok(Verified::NotFinished),
        Completion::Damaged(why) => (why, false),
        Completion::Done(record) => {
            let stamp = std::fs::metadata(layout.shard_file(shard))
                .map(|m| file_stamp(&m))
                .ok();
            if record.stamp == stamp || !repair {
                return Ok(Verified::Good {
                    record,
                    restamped: false,
                });
            }
            ("its stamp changed".to_string(), true)
        }
    };
    if !repair {
        return Ok(Verified::Damaged {
            reason,
            moved_to: None,
        });
    }
    let owner = lease::owner_name();
    let held = match lease::acquire(&layout.lease(shard), &owner, 60.0)? {
        lease::Acquired::Held(l) => l,
        lease::Acquired::Busy(h) => {
            return Ok(Verified::Busy {
                reason,
                owner: h.owner,
            })
        }
        lease::Acquired::Contended => {
            return Ok(Verified::Busy {
                reason,
                owner: "several workers".into(),
            })
        }
    };
    // Look again under the lease: a worker may have changed the shard meanwhile.
    let result = match completion(layout, shard, fingerprint, Check::Full) {
        Err(e) => Err(e),
        Ok(Completion::Absent) => Ok(Verified::NotFinished),
        Ok(Completion::Damaged(why)) => {
            quarantine(layout, shard, &why).map(|to| Verified::Damaged {
                reason: why,
                moved_to: Some(to),
            })
        }
        Ok(Completion::Done(mut record)) => (|| {
            let file = layout.shard_file(shard);
            let meta =
                std::fs::metadata(&file).map_err(|e| WorkerError::io("reading", &file, e))?;
            let restamped = restamp && record.stamp != Some(file_stamp(&meta));
            if restamped {
                record.stamp = Some(file_stamp(&meta));
                let json =
                    serde_json::to_vec_pretty(&record).map_err(|e| WorkerError::BadFile {
                        path: layout.completion(shard),
                        reason: e.to_string(),
                    })?;
                crate::fsutil::write_atomic(
                    &layout.completion(shard),
                    &json,
                    "re-recording the shard's stamp",
                )?;
            }
            Ok(Verified::Good { record, restamped })
        })(),
    };
    held.release();
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(bytes: &[u8]) -> CompletionRecord {
        use sha2::{Digest, Sha256};
        CompletionRecord {
            schema_version: sparc3d_schema::SCHEMA_VERSION,
            fingerprint: "fp".into(),
            rows: 1,
            ok: 1,
            bytes: bytes.len() as u64,
            sha256: sparc3d_schema::job::config::hex(&Sha256::digest(bytes)),
            ..Default::default()
        }
    }

    fn write(layout: &JobLayout, data: &[u8], rec: &CompletionRecord) -> Result<()> {
        create_dir(&layout.shards_dir())?;
        let file = layout.shard_file(0);
        std::fs::write(&file, data).map_err(|e| WorkerError::io("t", &file, e))?;
        let mut rec = rec.clone();
        let meta = std::fs::metadata(&file).map_err(|e| WorkerError::io("t", &file, e))?;
        rec.stamp = Some(file_stamp(&meta));
        let json = serde_json::to_vec(&rec).map_err(|e| WorkerError::Child(e.to_string()))?;
        let path = layout.completion(0);
        std::fs::write(&path, json).map_err(|e| WorkerError::io("t", &path, e))
    }

    fn set_mtime(path: &std::path::Path, to: std::time::SystemTime) -> Result<()> {
        std::fs::File::options()
            .write(true)
            .open(path)
            .and_then(|f| f.set_modified(to))
            .map_err(|e| WorkerError::io("t", path, e))
    }

    /// Issue 10, item 2: a byte flipped inside a finished shard, even with its modification
    /// time put back, is found by both checks; a torn record (item 4) is damage, not an error.
    #[test]
    fn flipped_byte_and_torn_record_are_damage() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tmp", "/tmp", e))?;
        let layout = JobLayout::new(dir.path());
        let data = b"a finished shard's bytes".to_vec();
        let rec = record(&data);
        write(&layout, &data, &rec)?;
        for check in [Check::Quick, Check::Full] {
            let c = completion(&layout, 0, "fp", check)?;
            assert!(matches!(c, Completion::Done(_)), "{c:?}");
        }
        // Flip one byte, same size, and set the modification time back.
        let file = layout.shard_file(0);
        let before = std::fs::metadata(&file)
            .and_then(|m| m.modified())
            .map_err(|e| WorkerError::io("t", &file, e))?;
        let mut bad = data.clone();
        bad[7] ^= 0x20;
        std::fs::write(&file, &bad).map_err(|e| WorkerError::io("t", &file, e))?;
        set_mtime(&file, before)?;
        for check in [Check::Quick, Check::Full] {
            let c = completion(&layout, 0, "fp", check)?;
            assert!(
                matches!(&c, Completion::Damaged(why) if why.contains("sha256")),
                "{check:?}: {c:?}"
            );
            assert!(matches!(
                shard_state(&layout, 0, "fp", check)?,
                ShardState::Damaged(_)
            ));
        }
        // Moved aside, it is simply not finished; the bytes are kept.
        let aside = quarantine(&layout, 0, "test")?;
        assert_eq!(
            completion(&layout, 0, "fp", Check::Full)?,
            Completion::Absent
        );
        let kept = std::fs::read(aside.join("part-00000.parquet"))
            .map_err(|e| WorkerError::io("t", &aside, e))?;
        assert_eq!(kept, bad);
        let note = std::fs::read_to_string(aside.join("reason.txt"))
            .map_err(|e| WorkerError::io("t", &aside, e))?;
        assert!(
            note.contains("part-00000.complete.json, part-00000.parquet"),
            "{note}"
        );

        // A torn record.
        write(&layout, &data, &rec)?;
        let path = layout.completion(0);
        let json = std::fs::read(&path).map_err(|e| WorkerError::io("t", &path, e))?;
        std::fs::write(&path, &json[..json.len() / 2])
            .map_err(|e| WorkerError::io("t", &path, e))?;
        let c = completion(&layout, 0, "fp", Check::Quick)?;
        assert!(
            matches!(&c, Completion::Damaged(why) if why.contains("does not parse")),
            "{c:?}"
        );
        // Another config's record stays an error.
        let mut other = rec.clone();
        other.fingerprint = "other".into();
        write(&layout, &data, &other)?;
        assert!(completion(&layout, 0, "fp", Check::Quick).is_err());
        Ok(())
    }
}
