//! `sparc3d inspect SHARD|JOB [--json]`: schema version, rows, bytes per column, percentiles
//! of voxel counts, faces and timings, the values of the provenance columns (`manifest.*`)
//! with their counts, and the content digest (which excludes timings) with the items digest
//! (the same rows hashed in item order, whatever the shards: docs/FORMAT.md, "Content
//! digest").
//!
//! Every finished shard is hashed against its completion record first (a shard file given
//! alone, when its record lies beside it): a damaged shard is named and the command fails
//! instead of reporting fewer rows or another digest.
//!
//! `--where FILTER` reports only the rows that pass (`crate::rows::row_filter`): their counts,
//! percentiles, provenance values and digests; the bytes stay those of the whole shards.

use crate::rows::row_filter::RowFilter;
use crate::rows::summary::shard_states;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use sparc3d_schema::row::digest;
use sparc3d_schema::{meta_keys, ItemStatus};
use sparc3d_workers::store::footer::read_meta;
use sparc3d_workers::store::read::{self, for_each_row};
use sparc3d_workers::store::state::{check_file, Check, ShardState};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A shard file or a job folder.
    pub target: PathBuf,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Only the rows that pass this filter, in `init --where`'s language over the shards'
    /// columns: `input_faces <= 1000000 and license in (cc0, cc-by)`.
    #[arg(long = "where", value_name = "FILTER")]
    pub filter: Option<String>,
}

/// What `--where` chose.
#[derive(Debug, Serialize)]
struct Chosen {
    /// The filter as written.
    #[serde(rename = "where")]
    text: String,
    /// Rows that did not pass (not in the rest of the report).
    rows_left_out: u64,
}

#[derive(Debug, Default, Serialize)]
struct Report {
    shards: u64,
    row_groups: usize,
    schema_versions: Vec<String>,
    rows: u64,
    ok: u64,
    failed: u64,
    file_bytes: u64,
    column_bytes: BTreeMap<String, u64>,
    percentiles: BTreeMap<String, BTreeMap<String, f64>>,
    time_sums: BTreeMap<String, f64>,
    /// Rows per value of each provenance column (`""` for none).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    provenance: BTreeMap<String, BTreeMap<String, u64>>,
    content_digest: String,
    /// What `--where` chose, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    filter: Option<Chosen>,
    /// The rows' content in item order, one hash over all shards: the same for a job grown by
    /// `add` and one made with all its items at once.
    items_digest: String,
}

/// Values of a provenance column printed in full; the rest are counted.
const VALUES_SHOWN: usize = 5;

const STATS: [&str; 6] = [
    "active_vertices",
    "active_cells",
    "input_faces",
    "output_faces",
    "time_convert_s",
    "time_total_s",
];

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// The completion record beside a shard file (`part-N.parquet` → `part-N.complete.json`).
fn record_beside(file: &Path) -> Option<PathBuf> {
    let name = file.file_name()?.to_str()?.strip_suffix(".parquet")?;
    Some(file.with_file_name(format!("{name}.complete.json")))
}

/// Checks a shard file given alone against the completion record beside it, if any.
fn check_alone(file: &Path) -> Result<()> {
    let Some(record) = record_beside(file).filter(|r| r.exists()) else {
        return Ok(());
    };
    let bytes = std::fs::read(&record).with_context(|| format!("reading {}", record.display()))?;
    let rec: sparc3d_schema::CompletionRecord = serde_json::from_slice(&bytes)
        .with_context(|| format!("{}: the completion record does not parse", record.display()))?;
    if let Some(why) = check_file(file, &rec, Check::Full)? {
        bail!("{} is damaged: {why}", file.display());
    }
    Ok(())
}

/// The finished shard files of a job (each hashed against its record), or the one file given.
fn shard_files(target: &Path) -> Result<Vec<PathBuf>> {
    if target.is_file() {
        check_alone(target)?;
        return Ok(vec![target.to_path_buf()]);
    }
    let job = crate::job::setup::open_read_only(target)?;
    let mut files = Vec::new();
    let mut damaged = Vec::new();
    for (shard, state) in (0..).zip(shard_states(&job, Check::Full)?) {
        match state {
            ShardState::Done(_) => files.push(job.layout.shard_file(shard)),
            ShardState::Damaged(why) => {
                damaged.push(format!("{:#}", read::damaged(&job, shard, &why)))
            }
            ShardState::Running(_) | ShardState::Pending => {}
        }
    }
    if !damaged.is_empty() {
        bail!(
            "{} damaged shard(s); no report of a partial job:\n  {}",
            damaged.len(),
            damaged.join("\n  ")
        );
    }
    if files.is_empty() {
        bail!("{}: no finished shard yet", target.display());
    }
    Ok(files)
}

/// Runs `sparc3d inspect`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    args.target = crate::job::bucket_home::local_view(&args.target)?;
    let files = shard_files(&args.target)?;
    let filter = match &args.filter {
        None => None,
        Some(text) if args.target.is_file() => {
            let schema = read::file_schema(&args.target)?;
            let what = args.target.display().to_string();
            Some(RowFilter::for_schema(&schema, text, &what)?)
        }
        Some(text) => {
            let job = crate::job::setup::open_read_only(&args.target)?;
            Some(RowFilter::for_job(&job, text)?)
        }
    };
    let report = build_report(&files, args.target.is_file(), filter.as_ref())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report);
    }
    Ok(ExitCode::SUCCESS)
}

/// Reads every row of `files` into one report; `single_file` keeps that file's own digest
/// (the digest of a job is the combination of its shards' digests).
fn build_report(
    files: &[PathBuf],
    single_file: bool,
    filter: Option<&RowFilter>,
) -> Result<Report> {
    let mut r = Report {
        filter: filter.map(|f| Chosen {
            text: f.text.clone(),
            rows_left_out: 0,
        }),
        ..Report::default()
    };
    let mut values: BTreeMap<&str, Vec<f64>> = STATS.iter().map(|s| (*s, Vec::new())).collect();
    let mut digests = Vec::new();
    let mut items = sha2::Sha256::default();
    for file in files {
        digests.push(add_shard(&mut r, &mut values, &mut items, file, filter)?);
    }
    r.rows -= r.filter.as_ref().map_or(0, |c| c.rows_left_out);
    r.items_digest = {
        use sha2::Digest;
        sparc3d_schema::job::config::hex(&items.finalize())
    };
    r.content_digest = if digests.len() == 1 && single_file {
        digests[0].clone()
    } else {
        digest::combine(&digests)
    };
    for (name, mut v) in values {
        v.sort_by(f64::total_cmp);
        let mut m = BTreeMap::new();
        for (label, p) in [("p50", 0.5), ("p90", 0.9), ("p99", 0.99), ("max", 1.0)] {
            m.insert(label.to_string(), percentile(&v, p));
        }
        m.insert("n".into(), v.len() as f64);
        r.percentiles.insert(name.to_string(), m);
    }
    Ok(r)
}

/// Adds one shard file's metadata, counts and timings to the report and returns its content
/// digest (hex).
fn add_shard(
    r: &mut Report,
    values: &mut BTreeMap<&str, Vec<f64>>,
    items: &mut sha2::Sha256,
    file: &Path,
    filter: Option<&RowFilter>,
) -> Result<String> {
    let meta = read_meta(file)?;
    r.shards += 1;
    let v = meta
        .kv
        .get(meta_keys::SCHEMA_VERSION)
        .cloned()
        .unwrap_or_else(|| "?".into());
    if !r.schema_versions.contains(&v) {
        r.schema_versions.push(v);
    }
    r.rows += meta.rows;
    r.row_groups += meta.row_groups;
    r.file_bytes += meta.file_bytes;
    for (c, b) in meta.column_bytes {
        if let Some(name) = c.strip_prefix(sparc3d_schema::columns::PROVENANCE_PREFIX) {
            r.provenance.entry(name.to_string()).or_default();
        }
        *r.column_bytes.entry(c).or_default() += b;
    }
    let mut push = |key: &str, x: f64| {
        if let Some(v) = values.get_mut(key) {
            v.push(x);
        }
    };
    let mut h = sha2::Sha256::default();
    for_each_row(file, |mut row| {
        if !passes(r, filter, &mut row)? {
            return anyhow::Ok(());
        }
        digest::update_row(&mut h, &row);
        digest::update_row(items, &row);
        for (name, values) in r.provenance.iter_mut() {
            let value = row.provenance.get(name).cloned().unwrap_or_default();
            *values.entry(value).or_default() += 1;
        }
        match row.status {
            ItemStatus::Ok => r.ok += 1,
            _ => r.failed += 1,
        }
        if let Some(k) = &row.counts {
            push("active_vertices", k.active_vertices as f64);
            push("active_cells", k.active_cells as f64);
            push("input_faces", k.input_faces as f64);
            if let Some(f) = k.output_faces {
                push("output_faces", f as f64);
            }
            push("time_convert_s", row.timings.convert_s);
        }
        let t = &row.timings;
        for (k, x) in [
            ("time_load_s", t.load_s),
            ("time_convert_s", t.convert_s),
            ("time_extract_s", t.extract_s),
            ("time_encode_s", t.encode_s),
            ("time_total_s", t.total_s),
        ] {
            *r.time_sums.entry(k.to_string()).or_default() += x;
        }
        push("time_total_s", row.timings.total_s);
        anyhow::Ok(())
    })?;
    use sha2::Digest;
    Ok(sparc3d_schema::job::config::hex(&h.finalize()))
}

/// Whether `row` passes `--where` (always without one); one that does not is counted in the
/// report's `filter.rows_left_out`.
fn passes(
    r: &mut Report,
    filter: Option<&RowFilter>,
    row: &mut sparc3d_schema::ShardRow,
) -> Result<bool> {
    let Some(f) = filter else {
        return Ok(true);
    };
    let keep = f.keeps(row, None)?;
    if let (false, Some(c)) = (keep, r.filter.as_mut()) {
        c.rows_left_out += 1;
    }
    Ok(keep)
}

/// Prints each provenance column with its most frequent values and their row counts.
fn print_provenance(r: &Report) {
    if r.provenance.is_empty() {
        return;
    }
    println!("provenance columns (rows per value):");
    for (name, values) in &r.provenance {
        let mut v: Vec<(&String, &u64)> = values.iter().collect();
        v.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        let shown: Vec<String> = v
            .iter()
            .take(VALUES_SHOWN)
            .map(|(value, n)| format!("{} {n}", if value.is_empty() { "(none)" } else { value }))
            .collect();
        let more = v.len().saturating_sub(VALUES_SHOWN);
        let more = if more > 0 {
            format!(", {more} more values")
        } else {
            String::new()
        };
        println!("  manifest.{name}: {}{more}", shown.join(", "));
    }
}

/// Prints the report as aligned text.
fn print_text(r: &Report) {
    println!("shards:         {}", r.shards);
    println!("schema version: {}", r.schema_versions.join(", "));
    println!(
        "rows:           {} ({} ok, {} failed) in {} row groups",
        r.rows, r.ok, r.failed, r.row_groups
    );
    println!("bytes:          {}", r.file_bytes);
    println!("content digest: {}", r.content_digest);
    println!("items digest:   {}", r.items_digest);
    if let Some(c) = &r.filter {
        println!(
            "where:          {} ({} rows left out; bytes are the whole shards')",
            c.text, c.rows_left_out
        );
    }
    print_provenance(r);
    println!("seconds summed over items:");
    for (k, v) in &r.time_sums {
        println!("  {v:>12.3}  {k}");
    }
    println!("bytes per column:");
    let mut cols: Vec<_> = r.column_bytes.iter().collect();
    cols.sort_by(|a, b| b.1.cmp(a.1));
    for (c, b) in cols {
        println!("  {b:>12}  {c}");
    }
    println!("percentiles:      p50          p90          p99          max");
    for (name, m) in &r.percentiles {
        let g = |k: &str| m.get(k).copied().unwrap_or(f64::NAN);
        println!(
            "  {name:<16} {:>12.3} {:>12.3} {:>12.3} {:>12.3}",
            g("p50"),
            g("p90"),
            g("p99"),
            g("max")
        );
    }
}
