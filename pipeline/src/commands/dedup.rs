//! `sparc3d dedup JOB [--threshold T] [--json]`: the job's near-duplicate groups, read from
//! the ok items' `shape_signature` column and grouped by [`crate::rows::near_duplicates`]: each
//! group's representative (its lowest item index) and the other members with their distance
//! to it. Writes nothing. `export` and `ls` keep one item per group with `--one-per-group`
//! ([`dropped_ids`]).

use crate::rows::near_duplicates::{groups, Group};
use crate::rows::row_filter::RowFilter;
use anyhow::{Context, Result};
use serde::Serialize;
use sparc3d_schema::ItemStatus;
use sparc3d_workers::store::read::{for_each_shard_row, Columns};
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;
use std::collections::{BTreeSet, HashSet};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The default threshold: the generated copies of the tests (moved, scaled, re-triangulated,
/// mirrored and jittered) sit within 0.008 of their originals at 96³, the closest distinct
/// shapes of one extent (a 15 % longer box and a cylinder) 0.09 apart (docs/QUALITY.md,
/// "Near-duplicates").
pub const DEFAULT_THRESHOLD: f64 = 0.03;

/// Arguments of `sparc3d dedup`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    #[command(flatten)]
    pub threshold: Threshold,
    /// Print one JSON document (groups, members, distances, the items one per group drops).
    #[arg(long)]
    pub json: bool,
}

/// The `--threshold` flag of `dedup` and of `--one-per-group` (`ls`, `export`).
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct Threshold {
    /// Largest signature distance of a member from its group's representative.
    #[arg(long = "threshold", default_value_t = DEFAULT_THRESHOLD, value_parser = parse_threshold)]
    pub value: f64,
}

/// `--one-per-group` (with its `--threshold`) of `ls` and `export`.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct OnePerGroup {
    /// Keep one item per near-duplicate group, its representative (`sparc3d dedup` lists
    /// the groups; with `--where`, the groups of the items that pass, so every group with a
    /// member that passes keeps one); items without a shape signature are kept.
    #[arg(long)]
    pub one_per_group: bool,
    /// `--one-per-group`'s threshold: largest signature distance from a representative.
    #[arg(long = "threshold", requires = "one_per_group", default_value_t = DEFAULT_THRESHOLD, value_parser = parse_threshold)]
    pub threshold: f64,
}

impl OnePerGroup {
    /// The ids to leave out: none without `--one-per-group`; an error when the job (`named`
    /// as given) stores no signatures. With a `--where` `filter`, the groups are those of the
    /// items it keeps, so each group with a member that passes keeps one of them.
    pub fn dropped(
        &self,
        job: &Job,
        named: &Path,
        filter: Option<&RowFilter>,
    ) -> Result<HashSet<String>> {
        match self.one_per_group {
            true => dropped_ids(job, named, self.threshold, filter),
            false => Ok(HashSet::new()),
        }
    }
}

fn parse_threshold(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("{s:?} is not a distance (a number ≥ 0)")),
    }
}

/// An ok item with a signature.
#[derive(Debug, Clone, Serialize)]
pub struct Signed {
    /// Its manifest position.
    pub index: u64,
    /// Its id.
    pub id: String,
    /// Its source.
    pub uri: String,
    #[serde(skip)]
    signature: Vec<f32>,
}

/// The job's ok items with their signatures, in item order, and those without one.
pub struct JobSignatures {
    /// Ok items with a signature.
    pub signed: Vec<Signed>,
    /// Ok items without one (ids): their output had no surface to measure.
    pub unsigned: Vec<String>,
}

/// Refuses a job whose config does not store the signatures (`shape_signature` off: made
/// before the column, or with it turned off), naming the job and what to do.
fn require_signatures(job: &Job, named: &Path) -> Result<()> {
    anyhow::ensure!(
        job.file.config.shape_signature,
        "{}: this job stores no shape signatures (its job.json has no `shape_signature = true`: \
         it was made before the column existed or with it off), so its items cannot be \
         grouped; convert them again in a new job (`shape_signature` is on by default)",
        named.display()
    );
    Ok(())
}

/// Reads every finished or running shard's ok rows (without their sample columns) that
/// `filter` keeps (every one without it); an error when the job does not store signatures
/// ([`require_signatures`]).
pub fn read_signatures(
    job: &Job,
    named: &Path,
    filter: Option<&RowFilter>,
) -> Result<JobSignatures> {
    require_signatures(job, named)?;
    let shards: BTreeSet<u64> = (0..job.file.shards).collect();
    let mut out = JobSignatures {
        signed: Vec::new(),
        unsigned: Vec::new(),
    };
    for shard in shards {
        for_each_shard_row(
            job,
            shard,
            Check::Quick,
            Columns::WithoutSamples,
            |mut row| {
                if row.status != ItemStatus::Ok {
                    return Ok(());
                }
                if let Some(f) = filter {
                    // A representative the filter leaves out would take its group with it.
                    let item = job.item(row.item_index)?;
                    if !f.keeps(&mut row, item.as_ref())? {
                        return Ok(());
                    }
                }
                match row.shape_signature {
                    Some(signature) => out.signed.push(Signed {
                        index: row.item_index,
                        id: row.id,
                        uri: row.uri,
                        signature,
                    }),
                    None => out.unsigned.push(row.id),
                }
                Ok(())
            },
        )
        .with_context(|| format!("reading shard {shard}"))?;
    }
    out.signed.sort_by_key(|s| s.index);
    Ok(out)
}

/// The near-duplicate groups of the signed items (positions into `signed`).
pub fn group(signed: &[Signed], threshold: f64) -> Vec<Group> {
    let signatures: Vec<Vec<f32>> = signed.iter().map(|s| s.signature.clone()).collect();
    groups(&signatures, threshold)
}

/// The ids `--one-per-group` leaves out: every group member but its representative, the
/// groups formed among the items `filter` keeps (its representative is the lowest item index
/// that passes). Items without a signature are kept (said on stderr).
pub fn dropped_ids(
    job: &Job,
    named: &Path,
    threshold: f64,
    filter: Option<&RowFilter>,
) -> Result<HashSet<String>> {
    let read = read_signatures(job, named, filter)?;
    warn_unsigned(&read);
    let groups = group(&read.signed, threshold);
    Ok(groups
        .iter()
        .flat_map(|g| g.members.iter().map(|&(m, _)| read.signed[m].id.clone()))
        .collect())
}

/// Says on stderr which ok items have no signature, when any.
fn warn_unsigned(read: &JobSignatures) {
    if !read.unsigned.is_empty() {
        eprintln!(
            "warning: {} ok items have no shape signature (an output without area) and are in \
             no group",
            read.unsigned.len()
        );
    }
}

/// One member as `--json` prints it.
#[derive(Serialize)]
struct JsonMember<'a> {
    #[serde(flatten)]
    item: &'a Signed,
    distance: f64,
}

/// One group as `--json` prints it.
#[derive(Serialize)]
struct JsonGroup<'a> {
    representative: &'a Signed,
    members: Vec<JsonMember<'a>>,
}

/// The `--json` document.
#[derive(Serialize)]
struct JsonReport<'a> {
    threshold: f64,
    items: usize,
    without_signature: &'a [String],
    groups: Vec<JsonGroup<'a>>,
    /// The ids one item per group leaves out.
    dropped: Vec<&'a str>,
}

/// Runs `sparc3d dedup`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    let named = args.job.clone();
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let job = crate::job::setup::open_read_only(&args.job)?;
    let read = read_signatures(&job, &named, None)?;
    warn_unsigned(&read);
    let threshold = args.threshold.value;
    let found = group(&read.signed, threshold);
    let member = |&(m, d): &(usize, f64)| JsonMember {
        item: &read.signed[m],
        distance: d,
    };
    let report = JsonReport {
        threshold,
        items: read.signed.len() + read.unsigned.len(),
        without_signature: &read.unsigned,
        groups: found
            .iter()
            .map(|g| JsonGroup {
                representative: &read.signed[g.representative],
                members: g.members.iter().map(member).collect(),
            })
            .collect(),
        dropped: found
            .iter()
            .flat_map(|g| g.members.iter().map(|&(m, _)| read.signed[m].id.as_str()))
            .collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_groups(&report);
    }
    eprintln!(
        "{} ok items, {} with a signature: {} groups hold {} items; one per group drops {} \
         (threshold {threshold})",
        report.items,
        read.signed.len(),
        report.groups.len(),
        report
            .groups
            .iter()
            .map(|g| g.members.len() + 1)
            .sum::<usize>(),
        report.dropped.len()
    );
    Ok(ExitCode::SUCCESS)
}

/// The groups as text: a header per group, then its representative and each member with
/// its distance, tab-separated and escaped as `ls` does; stops quietly when the reader goes
/// away (`| head`).
fn print_groups(report: &JsonReport) {
    use sparc3d_manifests::tsv::field;
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    for (n, g) in report.groups.iter().enumerate() {
        let r = g.representative;
        let mut text = format!("group {}: {} items\n", n + 1, g.members.len() + 1);
        text += &format!(
            "  {}\t{}\trepresentative\t{}\n",
            r.index,
            field(&r.id),
            field(&r.uri)
        );
        for m in &g.members {
            let i = m.item;
            let (id, uri) = (field(&i.id), field(&i.uri));
            text += &format!("  {}\t{id}\t{:.4}\t{uri}\n", i.index, m.distance);
        }
        if out.write_all(text.as_bytes()).is_err() {
            return;
        }
    }
}
