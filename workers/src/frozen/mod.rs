//! A job's frozen manifest, as the commands read it: one shard's items, one item, or every item
//! streamed shard by shard, at the cost of what is read. A job keeps it in slices
//! ([`sliced`]: a task reads its own shard's slice and index page, never the rest), written by
//! [`write::SliceWriter`]; a job made before slices keeps it in one file, `manifest.jsonl`,
//! read whole as it always was ([`FrozenManifest::Whole`]).

pub mod lines;
pub mod sliced;
pub mod write;

use crate::error::Result;
pub use sliced::Sliced;
use sparc3d_schema::FrozenItem;

/// The frozen manifest of an opened job.
#[derive(Debug, Clone)]
pub enum FrozenManifest {
    /// A job made before slices: `manifest.jsonl`, read whole.
    Whole(Vec<FrozenItem>),
    /// Slices under `manifest/`, read on demand.
    Sliced(Sliced),
}

impl FrozenManifest {
    /// The items of `shard`, in manifest order (none for a shard the job does not have).
    pub fn shard_items(&self, shard: u64) -> Result<Vec<FrozenItem>> {
        match self {
            Self::Whole(items) => {
                let start = items.partition_point(|i| i.shard < shard);
                let end = items.partition_point(|i| i.shard <= shard);
                Ok(items[start..end.max(start)].to_vec())
            }
            Self::Sliced(s) => s.shard_items(shard),
        }
    }

    /// The item with index `index`, if the job has one.
    pub fn item(&self, index: u64) -> Result<Option<FrozenItem>> {
        match self {
            Self::Whole(items) => Ok(items.get(index as usize).cloned()),
            Self::Sliced(s) => s.item(index),
        }
    }

    /// Every item, in order, read a shard at a time (`shards`: the job's shard count).
    pub fn iter(&self, shards: u64) -> Items<'_> {
        Items {
            manifest: self,
            shards,
            next_shard: 0,
            buffer: Vec::new().into_iter(),
        }
    }

    /// Every item, in order, in memory: for the commands that need them all at once.
    pub fn load_all(&self, shards: u64) -> Result<Vec<FrozenItem>> {
        match self {
            Self::Whole(items) => Ok(items.clone()),
            Self::Sliced(_) => self.iter(shards).collect(),
        }
    }
}

/// Every item of a frozen manifest, in order, a shard's slice at a time
/// ([`FrozenManifest::iter`]); an unreadable slice is an error item, and the end.
#[derive(Debug)]
pub struct Items<'a> {
    manifest: &'a FrozenManifest,
    shards: u64,
    next_shard: u64,
    buffer: std::vec::IntoIter<FrozenItem>,
}

impl Iterator for Items<'_> {
    type Item = Result<FrozenItem>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(item) = self.buffer.next() {
                return Some(Ok(item));
            }
            if self.next_shard >= self.shards {
                return None;
            }
            let shard = self.next_shard;
            self.next_shard += 1;
            match self.manifest.shard_items(shard) {
                Ok(items) => self.buffer = items.into_iter(),
                Err(e) => {
                    self.next_shard = self.shards;
                    return Some(Err(e));
                }
            }
        }
    }
}
