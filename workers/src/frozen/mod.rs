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

#[cfg(test)]
mod tests {
    use super::write::SliceWriter;
    use super::*;
    use sparc3d_schema::{JobConfig, JobFile, JobLayout, ManifestRecord};

    fn record(i: u64) -> ManifestRecord {
        ManifestRecord {
            id: format!("item{i}"),
            uri: format!("/d/{i}.obj"),
            sha256: None,
            format: None,
            extra: Default::default(),
        }
    }

    /// A job file for `pages` written with shards of `size`.
    fn job_file(size: u32, pages: &[sparc3d_schema::ManifestPage]) -> JobFile {
        let config = JobConfig {
            shard_size: size,
            ..JobConfig::default()
        };
        JobFile {
            schema_version: sparc3d_schema::SCHEMA_VERSION,
            tool_version: "test".into(),
            fingerprint: String::new(),
            config,
            items: pages.iter().map(|p| p.items).sum(),
            shards: pages.iter().map(|p| p.shards).sum(),
            manifest_sha256: sparc3d_schema::job::manifest::index_sha256(pages),
            manifest_pages: Some(pages.to_vec()),
        }
    }

    /// Slices and pages written in batches read back as the items frozen in memory, one shard,
    /// one item or all; an add starts a new shard after a partial one and carries the last
    /// page on; an edited slice is refused naming it (strict) or read with a warning.
    #[test]
    fn slices_read_back_grow_and_refuse_an_edit() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| crate::WorkerError::io("tmp", "/tmp", e))?;
        let layout = JobLayout::new(dir.path());
        let mut w = SliceWriter::create(&layout, 3)?;
        w.push((0..4).map(record).collect())?;
        w.push((4..7).map(record).collect())?;
        let (pages, items) = w.finish()?;
        assert_eq!(items, 7);
        let file = job_file(3, &pages);
        let sliced = Sliced::new(&layout, &file, pages, true);
        let shards: Vec<usize> = (0..3)
            .map(|s| sliced.shard_items(s).map(|i| i.len()))
            .collect::<Result<_>>()?;
        assert_eq!(shards, [3, 3, 1]);
        let manifest = FrozenManifest::Sliced(sliced.clone());
        let ids: Vec<String> = manifest
            .iter(3)
            .map(|i| i.map(|i| i.record.id))
            .collect::<Result<_>>()?;
        assert_eq!(ids, (0..7).map(|i| format!("item{i}")).collect::<Vec<_>>());
        assert_eq!(manifest.item(5)?.map(|i| (i.shard, i.index)), Some((1, 5)));
        assert!(manifest.item(7)?.is_none());

        let mut grow = SliceWriter::append(&layout, &file, &sliced)?;
        grow.push((7..9).map(record).collect())?;
        let (pages, items) = grow.finish()?;
        assert_eq!((items, pages.len()), (9, 1));
        let grown_file = job_file(3, &pages);
        let grown = Sliced::new(&layout, &grown_file, pages, true);
        let last: Vec<(u64, u64)> = grown
            .shard_items(3)?
            .iter()
            .map(|i| (i.index, i.shard))
            .collect();
        assert_eq!(
            last,
            [(7, 3), (8, 3)],
            "shard 2 (one item) is never refilled"
        );
        assert_eq!(grown.shard_items(2)?.len(), 1);
        assert!(grown.problems().is_empty());

        let slice = layout.manifest_slice(1, &grown.entry(1)?.sha256);
        let text = std::fs::read_to_string(&slice).unwrap_or_default();
        std::fs::write(&slice, text.replace("/d/4.obj", "/d/x.obj"))
            .map_err(|e| crate::WorkerError::io("edit", &slice, e))?;
        let refused = grown
            .shard_items(1)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        let name = slice
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        assert!(
            refused.contains(&name) && refused.contains("edited"),
            "{refused}"
        );
        assert_eq!(grown.problems().len(), 1);
        assert!(
            grown.shard_items(0).is_ok(),
            "the other slices are read as they are"
        );
        let lenient = Sliced::new(&layout, &grown_file, grown.pages().to_vec(), false);
        assert_eq!(lenient.shard_items(1)?[1].record.uri, "/d/x.obj");
        Ok(())
    }
}
