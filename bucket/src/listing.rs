//! What a bucket job's shards have in the bucket, from one listing of the job's prefix from
//! `shards/` on (`shards/` then `state/`; `job.json` and the frozen manifest's files sort
//! before it and are not listed): the completion records, the shards' objects, the leases and
//! the checkpoints, each with its size and ETag. The read-only commands read only the objects
//! this listing shows, so their requests follow what the bucket holds, not the job's shard
//! count: a job of 39,000 shards none of which has started is one listing of nothing.

use crate::keys;
use anyhow::{Context, Result};
use sparc3d_sources::list::Listed;
use sparc3d_sources::objects::Prefix;
use std::collections::{BTreeMap, BTreeSet};

/// One listing of a bucket job's `shards/` and `state/`.
#[derive(Debug, Default)]
pub struct JobListing {
    /// The objects under `shards/` by name within it (records and uploads).
    shard_objects: BTreeMap<String, Listed>,
    /// Each shard's completion record.
    records: BTreeMap<u64, Listed>,
    /// The shards with a lease object.
    leases: BTreeSet<u64>,
    /// Each shard's checkpoints, by key relative to the job's prefix, sorted.
    journals: BTreeMap<u64, Vec<(String, Listed)>>,
}

impl JobListing {
    /// Lists the job at `prefix` from `shards/` on, in one listing.
    pub fn read(prefix: &Prefix<'_>) -> Result<Self> {
        let found = prefix
            .list_from(keys::SHARDS.trim_end_matches('/'))
            .with_context(|| format!("listing {}", prefix.url(keys::SHARDS)))?;
        let mut listing = Self::default();
        for listed in found {
            let key = prefix.relative_key(&listed);
            listing.add(key, listed);
        }
        Ok(listing)
    }

    fn add(&mut self, key: String, listed: Listed) {
        if let Some(name) = key.strip_prefix(keys::SHARDS) {
            if let Some(shard) = keys::shard_of(name).filter(|&s| keys::record(s) == key) {
                self.records.insert(shard, listed.clone());
            }
            self.shard_objects.insert(name.to_string(), listed);
        } else if let Some(shard) = keys::shard_of(&key) {
            if key == keys::lease(shard) {
                self.leases.insert(shard);
            } else if key.starts_with(&keys::journals(shard)) && key.ends_with(".journal") {
                self.journals.entry(shard).or_default().push((key, listed));
            }
        }
    }

    /// The objects under `shards/` by name within it.
    pub fn shard_objects(&self) -> &BTreeMap<String, Listed> {
        &self.shard_objects
    }

    /// The shards that have a completion record, with the record's object as listed.
    pub fn records(&self) -> &BTreeMap<u64, Listed> {
        &self.records
    }

    /// The shards with a lease.
    pub fn leased_shards(&self) -> impl Iterator<Item = u64> + '_ {
        self.leases.iter().copied()
    }

    /// The shards with checkpoints.
    pub fn journal_shards(&self) -> impl Iterator<Item = u64> + '_ {
        self.journals.keys().copied()
    }

    /// `shard`'s checkpoints (keys relative to the job's prefix, with what was listed).
    pub fn journals(&self, shard: u64) -> &[(String, Listed)] {
        self.journals.get(&shard).map_or(&[], Vec::as_slice)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lease::tests::memory_prefix;
    use sparc3d_sources::objects::WriteMode;

    #[test]
    fn one_listing_sorts_records_uploads_leases_and_checkpoints_by_shard() -> Result<()> {
        let prefix = memory_prefix();
        for key in [
            keys::JOB_FILE.to_string(),
            keys::manifest_file("part-00000.abc.jsonl"),
            keys::record(3),
            keys::data(&keys::data_name(3, "w1")),
            keys::lease(5),
            keys::checkpoint(5, "w2", 0),
            keys::checkpoint(5, "w2", 1),
            "state/part-00005.journals/stray.tmp".to_string(),
        ] {
            prefix.put(&key, b"{}".to_vec(), WriteMode::Create)?;
        }
        let listing = JobListing::read(&prefix)?;
        assert_eq!(listing.records().keys().collect::<Vec<_>>(), vec![&3]);
        assert!(listing
            .shard_objects()
            .contains_key(&keys::data_name(3, "w1")));
        assert_eq!(
            listing.shard_objects().len(),
            2,
            "the manifest is not listed"
        );
        assert_eq!(listing.leased_shards().collect::<Vec<_>>(), [5]);
        let journals: Vec<&str> = listing
            .journals(5)
            .iter()
            .map(|(k, _)| k.as_str())
            .collect();
        assert_eq!(
            journals,
            [keys::checkpoint(5, "w2", 0), keys::checkpoint(5, "w2", 1)]
        );
        assert!(listing.journals(3).is_empty());
        Ok(())
    }
}
