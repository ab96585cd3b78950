//! A frozen manifest kept in slices (`manifest/`): one file per shard with its items' frozen
//! lines, listed by index pages of [`PAGE_SHARDS`] shards each (a line per shard: its first
//! item, its item count, its slice's sha256), whose sha256s `job.json` pins. A task reads its
//! shard's page and slice and nothing else, each checked against what pins it, so a hand edit
//! of either is still found (naming the file), without reading or hashing the rest.

use super::lines::{self, Expected};
use crate::error::{Result, WorkerError};
use sparc3d_schema::job::manifest::PAGE_SHARDS;
use sparc3d_schema::{FrozenItem, JobFile, JobLayout, ManifestPage, SliceEntry};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

/// One shard's items as read from its slice.
type ShardSlice = (u64, Arc<Vec<FrozenItem>>);

/// The slices of a job's frozen manifest, read on demand, pages kept once read.
#[derive(Debug, Clone)]
pub struct Sliced {
    layout: JobLayout,
    pages: Vec<ManifestPage>,
    /// The index of each page's first item.
    page_first: Vec<u64>,
    shards: u64,
    shard_size: u64,
    /// Whether a file that is not the one pinned is refused (`run`, `work`, ...) rather than
    /// read with a warning (the read-only commands).
    strict: bool,
    loaded: Vec<OnceLock<Arc<Vec<SliceEntry>>>>,
    warned: Arc<Mutex<HashSet<PathBuf>>>,
    /// The slice [`Sliced::item`] read last: rows are looked up a shard at a time.
    last_slice: Arc<Mutex<Option<ShardSlice>>>,
}

impl Sliced {
    /// The slices of the job at `layout` whose job file is `file` (with `manifest_pages`).
    pub fn new(layout: &JobLayout, file: &JobFile, pages: Vec<ManifestPage>, strict: bool) -> Self {
        let mut page_first = Vec::with_capacity(pages.len());
        let mut first = 0;
        for p in &pages {
            page_first.push(first);
            first += p.items;
        }
        Self {
            layout: layout.clone(),
            loaded: pages.iter().map(|_| OnceLock::new()).collect(),
            pages,
            page_first,
            shards: file.shards,
            shard_size: u64::from(file.config.shard_size.max(1)),
            strict,
            warned: Arc::default(),
            last_slice: Arc::default(),
        }
    }

    /// The pages as `job.json` pins them.
    pub fn pages(&self) -> &[ManifestPage] {
        &self.pages
    }

    /// What `job.json`'s pages disagree with in its own counts (one line each); empty when
    /// they agree. Reads no file.
    pub fn pin_problems(&self, file: &JobFile) -> Vec<String> {
        let items: u64 = self.pages.iter().map(|p| p.items).sum();
        let shards: u64 = self.pages.iter().map(|p| p.shards).sum();
        let mut out = Vec::new();
        if items != file.items || shards != file.shards {
            out.push(format!(
                "job.json: its manifest_pages list {items} items in {shards} shards, but it \
                 records {} items in {} shards",
                file.items, file.shards
            ));
        }
        let short_page = self
            .pages
            .iter()
            .rev()
            .skip(1)
            .position(|p| p.shards != PAGE_SHARDS);
        if let Some(p) = short_page {
            out.push(format!(
                "job.json: manifest page {} lists {} shards; every page but the last lists \
                 {PAGE_SHARDS}",
                self.pages.len() - 2 - p,
                self.pages[self.pages.len() - 2 - p].shards
            ));
        }
        out
    }

    /// The entry of `shard` in its index page.
    pub fn entry(&self, shard: u64) -> Result<SliceEntry> {
        let page = self.page(shard / PAGE_SHARDS)?;
        let at = (shard % PAGE_SHARDS) as usize;
        page.get(at).cloned().ok_or_else(|| self.no_shard(shard))
    }

    /// The items of `shard`, in order (none for a shard the job does not have).
    pub fn shard_items(&self, shard: u64) -> Result<Vec<FrozenItem>> {
        if shard >= self.shards {
            return Ok(Vec::new());
        }
        let entry = self.entry(shard)?;
        let path = self.layout.manifest_slice(shard, &entry.sha256);
        let bytes = self.read_pinned(&path, &entry.sha256, "the index page")?;
        let expected = Expected {
            first: entry.first,
            shard: Some(shard),
        };
        let items = lines::parse(&path, &bytes, expected)?;
        if items.len() as u64 != entry.items || entry.items > self.shard_size {
            return Err(self.edited(format!(
                "{}: {} items, where its index page lists {} (at most {} a shard)",
                self.name(&path),
                items.len(),
                entry.items,
                self.shard_size
            )));
        }
        Ok(items)
    }

    /// The item with index `index`, if the job has one.
    pub fn item(&self, index: u64) -> Result<Option<FrozenItem>> {
        let p = self.page_first.partition_point(|&f| f <= index);
        let Some(page_no) = p.checked_sub(1) else {
            return Ok(None);
        };
        if index >= self.page_first[page_no] + self.pages[page_no].items {
            return Ok(None);
        }
        let page = self.page(page_no as u64)?;
        let at = page.partition_point(|e| e.first <= index);
        let Some(entry) = at.checked_sub(1).and_then(|a| page.get(a)) else {
            return Ok(None);
        };
        let at = (index - entry.first) as usize;
        if let Ok(last) = self.last_slice.lock() {
            if let Some((_, items)) = last.as_ref().filter(|(s, _)| *s == entry.shard) {
                return Ok(items.get(at).cloned());
            }
        }
        let items = Arc::new(self.shard_items(entry.shard)?);
        let found = items.get(at).cloned();
        if let Ok(mut last) = self.last_slice.lock() {
            *last = Some((entry.shard, items));
        }
        Ok(found)
    }

    /// Every page and slice checked against what pins it, reading each once (in parallel):
    /// what differs, one line each, the first 10 by shard (empty when the frozen manifest is
    /// as `init` and `add` wrote it).
    pub fn problems(&self) -> Vec<String> {
        use rayon::prelude::*;
        let found: Vec<String> = self
            .strictly(|s| {
                Ok((0..s.shards)
                    .into_par_iter()
                    .filter_map(|shard| s.shard_items(shard).err())
                    .map(|e| match e {
                        WorkerError::EditedJob { problems, .. } => problems.join("; "),
                        other => other.to_string(),
                    })
                    .collect())
            })
            .unwrap_or_default();
        let mut out: Vec<String> = found.iter().take(10).cloned().collect();
        if found.len() > 10 {
            out.push(format!("(and {} more)", found.len() - 10));
        }
        out
    }

    /// `f` run on a strict copy of these slices (pages read again).
    fn strictly<T>(&self, f: impl FnOnce(&Self) -> Result<T>) -> Result<T> {
        if self.strict {
            return f(self);
        }
        let strict = Self {
            strict: true,
            loaded: self.pages.iter().map(|_| OnceLock::new()).collect(),
            warned: Arc::default(),
            last_slice: Arc::default(),
            ..self.clone()
        };
        f(&strict)
    }

    /// Index page `page`'s entries, read and checked once.
    fn page(&self, page: u64) -> Result<Arc<Vec<SliceEntry>>> {
        let Some(slot) = self.loaded.get(page as usize) else {
            return Err(self.no_shard(page * PAGE_SHARDS));
        };
        if let Some(entries) = slot.get() {
            return Ok(Arc::clone(entries));
        }
        let entries = Arc::new(self.read_page(page)?);
        Ok(Arc::clone(slot.get_or_init(|| entries)))
    }

    fn read_page(&self, page: u64) -> Result<Vec<SliceEntry>> {
        let pin = &self.pages[page as usize];
        let path = self.layout.manifest_page(page, &pin.sha256);
        let bytes = self.read_pinned(&path, &pin.sha256, "job.json")?;
        let text = std::str::from_utf8(&bytes).map_err(|e| WorkerError::BadFile {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        let first_shard = page * PAGE_SHARDS;
        let mut next_first = self.page_first[page as usize];
        let mut entries = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let entry = SliceEntry::parse(line)
                .filter(|e| e.shard == first_shard + n as u64 && e.first == next_first)
                .ok_or_else(|| {
                    self.edited(format!(
                        "{}: line {} is not the entry of shard {} (first item {next_first})",
                        self.name(&path),
                        n + 1,
                        first_shard + n as u64
                    ))
                })?;
            next_first += entry.items;
            entries.push(entry);
        }
        let counted = next_first - self.page_first[page as usize];
        if entries.len() as u64 != pin.shards || counted != pin.items {
            return Err(self.edited(format!(
                "{}: {} shards of {counted} items, where job.json pins {} of {}",
                self.name(&path),
                entries.len(),
                pin.shards,
                pin.items
            )));
        }
        Ok(entries)
    }

    /// The bytes of `path`, which `pinned_by` records with sha256 `sha256`: one with other
    /// bytes is refused when strict, else read with a warning (once a file).
    fn read_pinned(&self, path: &Path, sha256: &str, pinned_by: &str) -> Result<Vec<u8>> {
        let bytes = std::fs::read(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => self.edited(format!(
                "{}: missing ({pinned_by} lists it with sha256 {sha256}; the frozen manifest's \
                 files are never removed once written)",
                self.name(path)
            )),
            _ => WorkerError::io("reading the frozen manifest", path, e),
        })?;
        let found = crate::fsutil::bytes_sha256(&bytes);
        if found == sha256 {
            return Ok(bytes);
        }
        let finding = format!(
            "{}: its sha256 is {found}, but {pinned_by} recorded {sha256} when it was frozen: \
             the frozen manifest was edited after `sparc3d init` (its paths, ids and shards \
             never change once frozen)",
            self.name(path)
        );
        if self.strict {
            return Err(self.edited(finding));
        }
        let first = self
            .warned
            .lock()
            .map(|mut w| w.insert(path.to_path_buf()))
            .unwrap_or(true);
        if first {
            eprintln!("warning: {}: {finding}", self.layout.root.display());
        }
        Ok(bytes)
    }

    /// `path` relative to the job folder, as findings name it.
    fn name(&self, path: &Path) -> String {
        path.strip_prefix(&self.layout.root)
            .unwrap_or(path)
            .display()
            .to_string()
    }

    fn edited(&self, finding: String) -> WorkerError {
        WorkerError::EditedJob {
            root: self.layout.root.clone(),
            problems: vec![finding],
        }
    }

    fn no_shard(&self, shard: u64) -> WorkerError {
        self.edited(format!(
            "{}: the index has no entry for shard {shard} of {}",
            JobLayout::MANIFEST_DIR,
            self.shards
        ))
    }
}
