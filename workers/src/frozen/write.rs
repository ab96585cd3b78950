//! Writing a frozen manifest in slices, streaming: records go in, in order, as many at a time
//! as the caller has; each full shard becomes its slice file and its line of an index page,
//! each full page its page file, and [`SliceWriter::finish`] gives the pages for `job.json`
//! to pin. Memory holds one shard's lines and one page's entries, whatever the manifest's
//! size. Files are named by their content's sha256 and never rewritten, so a job's files are
//! only ever added to: an `init` or `add` stopped half-way leaves files no `job.json` pins,
//! which the next one reuses or leaves, and removes what it made itself when it fails.

use super::sliced::Sliced;
use crate::error::{Result, WorkerError};
use crate::fsutil::bytes_sha256;
use rayon::prelude::*;
use sparc3d_schema::job::manifest::PAGE_SHARDS;
use sparc3d_schema::{FrozenItem, JobFile, JobLayout, ManifestPage, ManifestRecord, SliceEntry};
use std::path::{Path, PathBuf};

/// Writes a frozen manifest's slices and pages into a job folder's `manifest/`.
#[derive(Debug)]
pub struct SliceWriter {
    layout: JobLayout,
    shard_size: u64,
    /// Index of the next item.
    next_index: u64,
    /// The shard being filled.
    shard: u64,
    /// Its lines so far, and their count.
    open_slice: Vec<u8>,
    open_items: u64,
    /// The entries of the page being filled.
    open_page: Vec<SliceEntry>,
    /// The pages closed, in order.
    pages: Vec<ManifestPage>,
    /// Files this writer made (not there before): removed by [`SliceWriter::abandon`].
    made: Vec<PathBuf>,
}

impl SliceWriter {
    /// A writer of a new job's frozen manifest into `layout`'s `manifest/`, shards of
    /// `shard_size` items.
    pub fn create(layout: &JobLayout, shard_size: u32) -> Result<Self> {
        let dir = layout.manifest_dir();
        std::fs::create_dir_all(&dir).map_err(|e| WorkerError::io("creating", &dir, e))?;
        Ok(Self {
            layout: layout.clone(),
            shard_size: u64::from(shard_size.max(1)),
            next_index: 0,
            shard: 0,
            open_slice: Vec::new(),
            open_items: 0,
            open_page: Vec::new(),
            pages: Vec::new(),
            made: Vec::new(),
        })
    }

    /// A writer of items after the last of the sliced job `file` (whose slices `sliced` reads):
    /// indices from its item count on, in new shards after its last one (a partial last shard
    /// is never refilled), its last page's entries carried on when that page is not full.
    pub fn append(layout: &JobLayout, file: &JobFile, sliced: &Sliced) -> Result<Self> {
        let mut writer = Self::create(layout, file.config.shard_size)?;
        writer.next_index = file.items;
        writer.shard = file.shards;
        writer.pages = sliced.pages().to_vec();
        if writer.pages.last().is_some_and(|p| p.shards < PAGE_SHARDS) {
            writer.pages.pop();
            let first = writer.pages.len() as u64 * PAGE_SHARDS;
            for shard in first..file.shards {
                writer.open_page.push(sliced.entry(shard)?);
            }
        }
        Ok(writer)
    }

    /// Index the next item pushed gets.
    pub fn next_index(&self) -> u64 {
        self.next_index
    }

    /// Freezes `records` as the next items, in order (serialized in parallel), writing every
    /// shard they fill.
    pub fn push(&mut self, records: Vec<ManifestRecord>) -> Result<()> {
        let mut items = Vec::with_capacity(records.len());
        let (mut shard, mut filled) = (self.shard, self.open_items);
        for (k, record) in records.into_iter().enumerate() {
            if filled == self.shard_size {
                (shard, filled) = (shard + 1, 0);
            }
            items.push(FrozenItem {
                index: self.next_index + k as u64,
                shard,
                record,
            });
            filled += 1;
        }
        self.push_items(&items)
    }

    /// Writes `items` as they are (their own indices and shards: a job's items carried into
    /// slices), in order, each after the last pushed and in its shard or a later one.
    pub fn push_items(&mut self, items: &[FrozenItem]) -> Result<()> {
        let lines: Vec<Vec<u8>> = items
            .par_chunks(4096)
            .map(super::lines::write)
            .collect::<Result<_>>()?;
        let mut at = 0;
        for chunk in &lines {
            for line in chunk.split_inclusive(|&b| b == b'\n') {
                self.push_line(line, &items[at])?;
                at += 1;
            }
        }
        Ok(())
    }

    /// Appends one item's frozen line to the open slice, closing the slice before when the
    /// item starts the next shard.
    fn push_line(&mut self, line: &[u8], item: &FrozenItem) -> Result<()> {
        if item.shard != self.shard {
            self.close_slice()?;
            self.shard = item.shard;
        }
        self.open_slice.extend_from_slice(line);
        self.open_items += 1;
        self.next_index = item.index + 1;
        Ok(())
    }

    /// Writes the open slice (if it has items) and its page entry, and the page when full.
    fn close_slice(&mut self) -> Result<()> {
        if self.open_items == 0 {
            return Ok(());
        }
        let sha256 = bytes_sha256(&self.open_slice);
        let path = self.layout.manifest_slice(self.shard, &sha256);
        let bytes = std::mem::take(&mut self.open_slice);
        self.put(&path, &bytes)?;
        self.open_page.push(SliceEntry {
            shard: self.shard,
            first: self.next_index - self.open_items,
            items: self.open_items,
            sha256,
        });
        self.open_items = 0;
        if self.open_page.len() as u64 == PAGE_SHARDS {
            self.close_page()?;
        }
        Ok(())
    }

    /// Writes the open page (if it has entries).
    fn close_page(&mut self) -> Result<()> {
        if self.open_page.is_empty() {
            return Ok(());
        }
        let text: String = self.open_page.iter().map(SliceEntry::line).collect();
        let sha256 = bytes_sha256(text.as_bytes());
        let page = self.pages.len() as u64;
        self.put(&self.layout.manifest_page(page, &sha256), text.as_bytes())?;
        self.pages.push(ManifestPage {
            shards: self.open_page.len() as u64,
            items: self.open_page.iter().map(|e| e.items).sum(),
            sha256,
        });
        self.open_page.clear();
        Ok(())
    }

    /// Writes `bytes` at `path` (a temporary name, then a rename) unless it holds them already.
    fn put(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        match std::fs::read(path) {
            Ok(there) if there == bytes => return Ok(()),
            Ok(_) => {}
            Err(_) => self.made.push(path.to_path_buf()),
        }
        let tmp = path.with_extension(format!("tmp-{}", std::process::id()));
        let written = std::fs::write(&tmp, bytes)
            .and_then(|()| std::fs::rename(&tmp, path))
            .map_err(|e| WorkerError::io("writing the frozen manifest", path, e));
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written
    }

    /// Writes the last slice and page and makes every file durable; the pages, in order, for
    /// `job.json` to pin, and the items written in all.
    pub fn finish(mut self) -> Result<(Vec<ManifestPage>, u64)> {
        let finished = self.close_slice().and_then(|()| self.close_page());
        let synced = finished.and_then(|()| sync_files(&self.layout.manifest_dir()));
        if let Err(e) = synced {
            self.abandon();
            return Err(e);
        }
        Ok((std::mem::take(&mut self.pages), self.next_index))
    }

    /// Removes the files this writer made (an `init` or `add` that failed); files that were
    /// there before it are left.
    pub fn abandon(self) {
        for path in &self.made {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// Makes what was written under `dir` durable: the file system's pending writes (`syncfs`,
/// one call for every file) and the folder.
fn sync_files(dir: &Path) -> Result<()> {
    use std::os::fd::AsRawFd;
    let f = std::fs::File::open(dir).map_err(|e| WorkerError::io("opening folder", dir, e))?;
    // SAFETY: `f` is an open file descriptor for the duration of the call.
    if unsafe { libc::syncfs(f.as_raw_fd()) } != 0 {
        let e = std::io::Error::last_os_error();
        return Err(WorkerError::io("syncing the frozen manifest", dir, e));
    }
    crate::fsutil::sync_dir(dir)
}
