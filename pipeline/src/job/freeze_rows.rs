//! A folder's or manifest's rows frozen into a job's slices as they are read, for `init` and
//! `add`: one thread reads and parses batches of rows while another identifies, checks and
//! writes them ([`sparc3d_manifests::freeze::Freezer`] into
//! [`sparc3d_workers::frozen::write::SliceWriter`]), so memory holds a few batches and the
//! ids' keys whatever the manifest's size. On any refusal the files this freeze made are
//! removed.

use super::rows::InputRows;
use anyhow::{anyhow, Result};
use sparc3d_manifests::freeze::{Freezer, Frozen};
use sparc3d_manifests::RawRecord;
use sparc3d_schema::ManifestPage;
use sparc3d_workers::frozen::write::SliceWriter;
use std::sync::mpsc::sync_channel;

/// Rows between two progress lines on stderr.
const PROGRESS_ROWS: u64 = 1_000_000;

/// What a freeze wrote: the pages for `job.json` to pin, the item count after it, and what
/// the freezer counted.
#[derive(Debug)]
pub struct Written {
    /// The index pages, in order (the job's earlier ones first, when it grew).
    pub pages: Vec<ManifestPage>,
    /// Items in the job after the freeze.
    pub items: u64,
    /// What was frozen now.
    pub frozen: Frozen,
}

/// Freezes every row of `rows` with `freezer` into `writer`; the rows' own refusals (no path
/// column, rows without a source, none passing `--where`) come before the freezer's.
pub fn freeze_rows(
    rows: &mut InputRows,
    mut freezer: Freezer,
    mut writer: SliceWriter,
) -> Result<Written> {
    let pushed = std::thread::scope(|scope| {
        let (send, receive) = sync_channel::<Vec<(u64, RawRecord)>>(2);
        let source = &mut *rows;
        let reader = scope.spawn(move || -> Result<()> {
            loop {
                let batch = source.next_batch()?;
                if batch.is_empty() || send.send(batch).is_err() {
                    return Ok(());
                }
            }
        });
        let mut written: Result<()> = Ok(());
        let mut next_note = PROGRESS_ROWS;
        for batch in receive {
            let last_row = batch.last().map_or(0, |(n, _)| *n);
            let records = freezer.batch(batch);
            if written.is_ok() && !freezer.failed() {
                written = writer.push(records).map_err(anyhow::Error::from);
            }
            if last_row >= next_note {
                eprintln!(
                    "{} rows read, {} items frozen",
                    last_row,
                    writer.next_index()
                );
                next_note += PROGRESS_ROWS;
            }
        }
        let read = reader
            .join()
            .map_err(|_| anyhow!("the manifest reader stopped unexpectedly"))?;
        read.and(written)
    });
    let checked = pushed
        .and_then(|()| rows.finish())
        .and_then(|()| freezer.finish());
    let frozen = match checked {
        Ok(frozen) => frozen,
        Err(e) => {
            writer.abandon();
            return Err(e);
        }
    };
    let (pages, items) = writer.finish()?;
    Ok(Written {
        pages,
        items,
        frozen,
    })
}
