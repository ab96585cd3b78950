//! Reproducible samples of a job's `ok` items, shared by `sparc3d validate` and
//! `sparc3d eval JOB --sample N`.
//!
//! Every item gets a key: the first 8 bytes (big-endian) of
//! `sha256(seed as 8 little-endian bytes ‖ id as UTF-8)`. The `ok` items are sorted by
//! (key, id) and the first k are the sample. The key depends on the seed and the id alone, so
//! the sample is the same whatever the number of workers, shards or runs that produced the
//! rows, and a larger sample (same seed) contains every smaller one.

use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};
use sparc3d_schema::{ItemStatus, ShardRow};
use sparc3d_workers::store::read::{for_each_row, shard_rows};
use sparc3d_workers::Job;
use std::str::FromStr;

/// How many items to sample: a percentage of the `ok` items (`2%`) or a count (`50`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleSize {
    /// A fraction of the `ok` items, in `0..=1` (`2%` is 0.02); rounded up, at least one item
    /// when the fraction is above zero.
    Fraction(f64),
    /// A number of items (all of them when there are fewer).
    Count(usize),
    /// A fraction of the `ok` items, but at least this many (all of them when there are
    /// fewer): a small job's sample still means something.
    FractionAtLeast(f64, usize),
}

impl SampleSize {
    /// The number of items to take out of `n`.
    pub fn of(&self, n: usize) -> usize {
        match *self {
            SampleSize::Count(k) => k.min(n),
            SampleSize::Fraction(f) if f <= 0.0 || n == 0 => 0,
            SampleSize::Fraction(f) => ((f * n as f64).ceil() as usize).clamp(1, n),
            SampleSize::FractionAtLeast(f, k) => SampleSize::Fraction(f).of(n).max(k.min(n)),
        }
    }
}

impl FromStr for SampleSize {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let s = s.trim();
        if let Some(p) = s.strip_suffix('%') {
            let p: f64 = p
                .trim()
                .parse()
                .map_err(|_| format!("{s:?} is not a percentage (e.g. 2%)"))?;
            if !(0.0..=100.0).contains(&p) {
                return Err(format!("{s:?}: a percentage must be within 0%..=100%"));
            }
            return Ok(SampleSize::Fraction(p / 100.0));
        }
        s.parse::<usize>()
            .map(SampleSize::Count)
            .map_err(|_| format!("{s:?} is neither a percentage (2%) nor a count (50)"))
    }
}

impl std::fmt::Display for SampleSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SampleSize::Fraction(x) => write!(f, "{}%", x * 100.0),
            SampleSize::Count(k) => write!(f, "{k}"),
            SampleSize::FractionAtLeast(x, k) => write!(f, "{}% but at least {k}", x * 100.0),
        }
    }
}

/// The sampling key of an item: first 8 bytes of `sha256(seed_le ‖ id)`, big-endian.
pub fn sample_key(seed: u64, id: &str) -> u64 {
    let mut h = Sha256::new();
    h.update(seed.to_le_bytes());
    h.update(id.as_bytes());
    let d = h.finalize();
    let mut b = [0u8; 8];
    b.copy_from_slice(&d[..8]);
    u64::from_be_bytes(b)
}

/// The `k` ids with the smallest (key, id), in that order.
pub fn select<'a>(ids: impl IntoIterator<Item = &'a str>, seed: u64, k: usize) -> Vec<&'a str> {
    let mut keyed: Vec<(u64, &str)> = ids
        .into_iter()
        .map(|id| (sample_key(seed, id), id))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().take(k).map(|(_, id)| id).collect()
}

/// Calls `f` on every row of one shard: the finished Parquet file when its completion record
/// is valid, otherwise the rows journalled so far (none when the shard was never started).
pub fn for_each_shard_row(
    job: &Job,
    shard: u64,
    mut f: impl FnMut(ShardRow) -> Result<()>,
) -> Result<()> {
    use sparc3d_workers::store::state::{completion, Check, Completion};
    match completion(&job.layout, shard, job.fingerprint(), Check::Quick)
        .with_context(|| format!("reading the completion record of shard {shard}"))?
    {
        Completion::Done(_) => return for_each_row(&job.layout.shard_file(shard), f),
        Completion::Damaged(why) => {
            return Err(sparc3d_workers::store::read::damaged(job, shard, &why).into())
        }
        Completion::Absent => {}
    }
    for row in
        shard_rows(job, shard, Check::Quick).with_context(|| format!("reading shard {shard}"))?
    {
        f(row)?;
    }
    Ok(())
}

/// Manifest positions (`item_index`) of a job's `ok` rows, in item order.
pub fn ok_items(job: &Job) -> Result<Vec<u64>> {
    let mut ok = Vec::new();
    for shard in 0..job.file.shards {
        for_each_shard_row(job, shard, |row| {
            if row.status == ItemStatus::Ok {
                ok.push(row.item_index);
            }
            Ok(())
        })?;
    }
    ok.sort_unstable();
    ok.dedup();
    Ok(ok)
}

/// A sample of a job's `ok` items.
#[derive(Debug, Clone)]
pub struct Sample {
    /// `ok` items in the job when the sample was drawn.
    pub population: usize,
    /// Manifest positions of the sampled items, in item order.
    pub items: Vec<u64>,
}

/// Draws a sample of `size` of the job's `ok` items with `seed` (see the module doc).
pub fn draw(job: &Job, size: SampleSize, seed: u64) -> Result<Sample> {
    let ok = ok_items(job)?;
    let mut ids = Vec::with_capacity(ok.len());
    for &i in &ok {
        let Some(item) = job.item(i)? else {
            bail!(
                "a shard row has item_index {i}, but the manifest of {} has {} items",
                job.layout.root.display(),
                job.file.items
            );
        };
        ids.push(item.record.id);
    }
    let chosen: std::collections::HashSet<&str> =
        select(ids.iter().map(String::as_str), seed, size.of(ids.len()))
            .into_iter()
            .collect();
    let items = ok
        .iter()
        .zip(&ids)
        .filter(|(_, id)| chosen.contains(id.as_str()))
        .map(|(&i, _)| i)
        .collect();
    Ok(Sample {
        population: ok.len(),
        items,
    })
}

/// Calls `f` on the row of every sampled item, in item order, reading only the shards that hold
/// one.
pub fn for_each_sampled_row(
    job: &Job,
    sample: &Sample,
    mut f: impl FnMut(ShardRow) -> Result<()>,
) -> Result<()> {
    let wanted: std::collections::BTreeSet<u64> = sample.items.iter().copied().collect();
    let mut shards: Vec<u64> = sample
        .items
        .iter()
        .filter_map(|&i| job.item(i).ok().flatten().map(|it| it.shard))
        .collect();
    shards.sort_unstable();
    shards.dedup();
    for shard in shards {
        for_each_shard_row(job, shard, |row| {
            if row.status == ItemStatus::Ok && wanted.contains(&row.item_index) {
                f(row)?;
            }
            Ok(())
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_round_up() {
        assert_eq!("2%".parse::<SampleSize>(), Ok(SampleSize::Fraction(0.02)));
        assert_eq!("17".parse::<SampleSize>(), Ok(SampleSize::Count(17)));
        assert!("x".parse::<SampleSize>().is_err());
        assert!("150%".parse::<SampleSize>().is_err());
        assert!("-1".parse::<SampleSize>().is_err());
        assert_eq!(SampleSize::Fraction(0.01).of(1000), 10);
        assert_eq!(SampleSize::Fraction(0.01).of(5), 1);
        assert_eq!(SampleSize::Fraction(0.0).of(5), 0);
        assert_eq!(SampleSize::Fraction(1.0).of(5), 5);
        assert_eq!(SampleSize::Count(10).of(3), 3);
        assert_eq!(SampleSize::FractionAtLeast(0.01, 20).of(30), 20);
        assert_eq!(SampleSize::FractionAtLeast(0.01, 20).of(12), 12);
        assert_eq!(SampleSize::FractionAtLeast(0.01, 20).of(5000), 50);
    }

    #[test]
    fn selection_depends_on_seed_and_ids_only() {
        let ids: Vec<String> = (0..200).map(|i| format!("item-{i}")).collect();
        let a = select(ids.iter().map(String::as_str), 7, 20);
        let mut reversed = ids.clone();
        reversed.reverse();
        let b = select(reversed.iter().map(String::as_str), 7, 20);
        assert_eq!(a, b, "input order must not matter");
        let small = select(ids.iter().map(String::as_str), 7, 5);
        assert_eq!(
            &a[..5],
            &small[..],
            "a larger sample contains a smaller one"
        );
        let other = select(ids.iter().map(String::as_str), 8, 20);
        assert_ne!(a, other, "another seed gives another sample");
        // The key is documented: first 8 bytes of sha256(seed_le ‖ id), big-endian.
        let mut h = Sha256::new();
        h.update(7u64.to_le_bytes());
        h.update(b"item-3");
        let d = h.finalize();
        assert_eq!(
            sample_key(7, "item-3"),
            u64::from_be_bytes([d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7]])
        );
    }
}
