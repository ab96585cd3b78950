//! Where things live in a job whose home is a bucket: the keys of a job folder's files
//! (schema/src/job/layout.rs), relative to the job's prefix, plus the names that only a bucket
//! needs.
//!
//! ```text
//! P/job.json, P/manifest/...                     as in a job folder (job.json written last)
//! P/manifest.jsonl                               the frozen manifest of a job made before slices
//! P/shards/part-NNNNN.complete.json              the completion record, created only if absent;
//!                                                its `object` names the shard's data
//! P/shards/part-NNNNN.<writer>.parquet           one writer's upload of the shard
//! P/state/part-NNNNN.lease                       the lease, taken and renewed by conditional writes
//! P/state/part-NNNNN.journals/<writer>.<seq>.journal   checkpoints: the items a holder finished
//! ```

use sparc3d_schema::{CompletionRecord, JobLayout};

/// `job.json`.
pub const JOB_FILE: &str = "job.json";

/// `manifest.jsonl`: the frozen manifest of a job made before slices.
pub const MANIFEST: &str = "manifest.jsonl";

/// `manifest/`: the frozen manifest's slices and index pages (names as in a job folder,
/// `sparc3d_schema::JobLayout::page_name` and `slice_name`; created once, never replaced).
pub const MANIFEST_FILES: &str = "manifest/";

/// The key of the frozen manifest's file `name` (a slice or an index page).
pub fn manifest_file(name: &str) -> String {
    format!("{MANIFEST_FILES}{name}")
}

/// `shards/`.
pub const SHARDS: &str = "shards/";

/// The completion record of `shard`.
pub fn record(shard: u64) -> String {
    format!("shards/{}.complete.json", JobLayout::shard_name(shard))
}

/// The name (within `shards/`) of `writer`'s upload of `shard`.
pub fn data_name(shard: u64, writer: &str) -> String {
    format!("{}.{writer}.parquet", JobLayout::shard_name(shard))
}

/// The key of a data object named `name` in `shards/`.
pub fn data(name: &str) -> String {
    format!("shards/{name}")
}

/// The lease of `shard`.
pub fn lease(shard: u64) -> String {
    format!("state/{}.lease", JobLayout::shard_name(shard))
}

/// The folder of `shard`'s checkpoints.
pub fn journals(shard: u64) -> String {
    format!("state/{}.journals/", JobLayout::shard_name(shard))
}

/// Checkpoint `seq` of `writer` on `shard`: names sort by writer, then by sequence.
pub fn checkpoint(shard: u64, writer: &str, seq: u32) -> String {
    format!("{}{writer}.{seq:06}.journal", journals(shard))
}

/// The shard index of a key under `shards/` or `state/` (`part-NNNNN...`), if it has one.
pub fn shard_of(name: &str) -> Option<u64> {
    let at = name.rfind("part-")?;
    let digits = &name[at + "part-".len()..];
    let end = digits
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(digits.len());
    digits[..end].parse().ok()
}

/// The name of the object a record's shard is in.
pub fn object_name(shard: u64, record: &CompletionRecord) -> String {
    record
        .object
        .clone()
        .unwrap_or_else(|| format!("{}.parquet", sparc3d_schema::JobLayout::shard_name(shard)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_follow_the_folder_layout_and_sort_by_sequence() {
        assert_eq!(record(3), "shards/part-00003.complete.json");
        assert_eq!(
            data(&data_name(3, "h_1_ab")),
            "shards/part-00003.h_1_ab.parquet"
        );
        assert_eq!(lease(12), "state/part-00012.lease");
        assert!(checkpoint(1, "w", 9) < checkpoint(1, "w", 10));
        assert_eq!(shard_of("shards/part-00042.x.parquet"), Some(42));
        assert_eq!(
            shard_of("state/part-00007.journals/a.000001.journal"),
            Some(7)
        );
        assert_eq!(shard_of("shards/other.parquet"), None);
    }
}
