//! `sparc3d export JOB --format CONSUMER --out DIR [--ids …] [--frame …]`: writes the ok items
//! of a job in a consumer's own on-disk layout (docs/FORMAT.md, "Exports"), through
//! `sparc3d_formats`, which holds each consumer's recipe. The export is built in a folder
//! beside `--out` and moved into place at the end, so `--out` is never half written: it is
//! either absent, or a finished export, or (after a rerun) the new finished export.
//! `.sparc3d-export.json` in it says which job, consumer, frame and items it holds.
//! `--where FILTER` exports only the items whose row passes (`crate::rows::row_filter`).

use crate::rows::export_name::ExportNames;
use crate::rows::item_lookup;
use crate::rows::row_filter::RowFilter;
use anyhow::{bail, Context, Result};
use clap::builder::TypedValueParser;
use rayon::prelude::*;
use sparc3d_formats::{Consumer, ExportFile, Frame, Item, Listed, StoredSamples};
use sparc3d_manifests::source_id::names_files_of;
use sparc3d_schema::ShardRow;
use sparc3d_workers::store::read::{for_each_shard_row, Columns};
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The file that marks a folder as a finished export and says what it holds.
/// Hidden, so a loader that globs the folder for items (Hunyuan3D-2.1's) never meets it.
pub const EXPORT_RECORD: &str = ".sparc3d-export.json";

/// Arguments of `sparc3d export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// The consumer whose layout to write (docs/FORMAT.md, "Exports", has the table).
    #[arg(long, value_parser = consumer_parser())]
    pub format: Consumer,
    /// Output folder: created, or replaced whole when it holds an earlier export.
    #[arg(long)]
    pub out: PathBuf,
    /// Only these items (comma-separated or repeated), each named as `--id` elsewhere: its id,
    /// a unique prefix of it, or its source file (path or file name); default: every ok item.
    #[arg(long, value_delimiter = ',')]
    pub ids: Vec<String>,
    /// Frame of the points: the consumer's own by default (`consumer` for the grid layouts,
    /// `normalized` for vecset-npz); `source` and `normalized` where the layout allows them.
    #[arg(long, value_parser = frame_parser())]
    pub frame: Option<Frame>,
    /// Only the items whose row passes this filter, in `init --where`'s language over the
    /// shards' columns: `input_faces <= 1000000 and license in (cc0, cc-by)`.
    #[arg(long = "where", value_name = "FILTER")]
    pub filter: Option<String>,
    #[command(flatten)]
    pub dedup: super::dedup::OnePerGroup,
}

/// `--format`'s parser: the consumers' names, each with its `--help` line.
fn consumer_parser() -> impl clap::builder::TypedValueParser<Value = Consumer> {
    let values = Consumer::ALL
        .iter()
        .map(|c| clap::builder::PossibleValue::new(c.name()).help(c.about()));
    clap::builder::PossibleValuesParser::new(values).try_map(|name| {
        Consumer::from_name(&name).ok_or_else(|| format!("no consumer named {name}"))
    })
}

/// `--frame`'s parser.
fn frame_parser() -> impl clap::builder::TypedValueParser<Value = Frame> {
    clap::builder::PossibleValuesParser::new(Frame::ALL.map(|f| f.name())).try_map(|name| {
        Frame::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| format!("no frame named {name}"))
    })
}

/// Takes `--one-per-group`'s `dropped` ids out of the `wanted` ones (every item when none
/// were named) and says how many it took; an error when nothing is left.
fn leave_out_near_duplicates(
    job: &Job,
    wanted: &mut BTreeSet<String>,
    dropped: &std::collections::HashSet<String>,
) -> Result<()> {
    if dropped.is_empty() {
        return Ok(());
    }
    if wanted.is_empty() {
        *wanted = job
            .items()
            .map(|i| i.map(|i| i.record.id))
            .collect::<Result<_, _>>()?;
    }
    let asked = wanted.len();
    wanted.retain(|id| !dropped.contains(id));
    anyhow::ensure!(
        !wanted.is_empty(),
        "every item asked for is a near-duplicate --one-per-group leaves out (nothing written)"
    );
    eprintln!(
        "--one-per-group: {} near-duplicates left out",
        asked - wanted.len()
    );
    Ok(())
}

/// Runs `sparc3d export`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    // Messages name the job as given (a URL), not its local view.
    let named = args.job.clone();
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    super::export_debris::clear(&args.out, EXPORT_RECORD)?;
    let job = Job::open(&args.job)?;
    let consumer = args.format;
    let frame = args.frame.unwrap_or(consumer.frames()[0]);
    if !consumer.frames().contains(&frame) {
        eprintln!(
            "error: --format {} is written in the frame{} {}, not {}",
            consumer.name(),
            if consumer.frames().len() > 1 { "s" } else { "" },
            consumer
                .frames()
                .iter()
                .map(|f| f.name())
                .collect::<Vec<_>>()
                .join(", "),
            frame.name()
        );
        return Ok(ExitCode::from(2));
    }
    let samples = &job.file.config.samples;
    let missing = consumer.missing(samples.enabled.then_some(&samples.params));
    if !missing.is_empty() {
        eprintln!(
            "error: {}: --format {} needs samples this job does not draw (nothing was \
             written); make a job with --for {} (samples on, whose defaults serve every \
             consumer), or with these [samples] keys:\n  {}",
            named.display(),
            consumer.name(),
            consumer.name(),
            missing.join("\n  ")
        );
        return Ok(ExitCode::from(2));
    }
    let check = consumer.check(&job.file.config.params, frame);
    if !check.required.is_empty() {
        eprintln!(
            "error: {}: --format {} --frame {} needs a job converted with these settings; \
             initialise one with them (nothing was written):\n  {}",
            named.display(),
            consumer.name(),
            frame.name(),
            check.required.join("\n  ")
        );
        return Ok(ExitCode::from(2));
    }
    for w in &check.warnings {
        eprintln!("warning: --format {}: {w}", consumer.name());
    }
    // Each `--ids` entry names an item as `--id` does elsewhere (whole id, unique prefix or
    // source file); a miss fails before anything is written, with the closest names.
    let mut wanted: BTreeSet<String> = BTreeSet::new();
    for query in &args.ids {
        wanted.insert(item_lookup::find(&job, query)?.record.id);
    }
    let filter = RowFilter::optional(&job, args.filter.as_deref())?;
    let dropped = args.dedup.dropped(&job, &named, filter.as_ref())?;
    leave_out_near_duplicates(&job, &mut wanted, &dropped)?;
    refuse_a_folder_that_is_not_an_export(&args.out)?;
    let staging = Staging::create(&args.out)?;
    let chosen = Chosen {
        ids: &wanted,
        filter: filter.as_ref(),
    };
    let written = write_items(&job, consumer, frame, &chosen, &staging.dir);
    let root = std::path::absolute(&args.out)
        .with_context(|| format!("resolving {}", args.out.display()))?;
    let outcome = written.and_then(|w| {
        write_listing(consumer, &w.listed, &root, &staging.dir)?;
        write_record(&job, consumer, frame, &w, &staging.dir, filter.as_ref())?;
        Ok(w)
    });
    let outcome = match outcome {
        Ok(w) => w,
        Err(e) => {
            staging.discard();
            return Err(e);
        }
    };
    if let Some(left) = staging.move_to(&args.out)? {
        eprintln!("warning: {left}");
    }
    eprintln!(
        "{} items written to {} ({}, frame {}){}",
        outcome.listed.len(),
        args.out.display(),
        consumer.name(),
        frame.name(),
        outcome.counts()
    );
    // Items left out as the consumer's own pipeline leaves them do not fail the export.
    Ok(if outcome.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// What the items' pass wrote.
#[derive(Default)]
struct Written {
    /// The items written, in manifest order.
    listed: Vec<Listed>,
    /// The items written with a note of what they lack (Step1X-3D's `sharp_surface`).
    noted: Vec<(String, &'static str)>,
    /// The items the consumer's own pipeline would leave out, with why (not failures).
    left_out: Vec<(String, String)>,
    /// The items that failed, with why.
    failed: Vec<(String, String)>,
    /// Ok items `--where` left out.
    filtered_out: u64,
}

impl Written {
    /// The summary's counts after the items written: each note and each reason for leaving
    /// items out with its count ("2 left out: no sharp edges, as Dora's own sampler"), then
    /// the failures; empty when there is none.
    fn counts(&self) -> String {
        let mut out = String::new();
        for (note, n) in tally(self.noted.iter().map(|(_, note)| *note)) {
            out.push_str(&format!(", {n} of them {note}"));
        }
        for (why, n) in tally(self.left_out.iter().map(|(_, why)| why.as_str())) {
            out.push_str(&format!(", {n} left out: {why}"));
        }
        if !self.failed.is_empty() {
            out.push_str(&format!(", {} failed", self.failed.len()));
        }
        if self.filtered_out > 0 {
            out.push_str(&format!(", {} left out by --where", self.filtered_out));
        }
        if !(self.noted.is_empty() && self.left_out.is_empty()) {
            out.push_str(&format!(" (ids in {EXPORT_RECORD})"));
        }
        out
    }
}

/// Each distinct text with how many times it comes, in order of the text.
fn tally<'a>(texts: impl Iterator<Item = &'a str>) -> BTreeMap<&'a str, usize> {
    let mut out = BTreeMap::new();
    for t in texts {
        *out.entry(t).or_insert(0) += 1;
    }
    out
}

/// Which ok items an export takes: those `--ids` names (all when empty) that pass `--where`.
struct Chosen<'a> {
    ids: &'a BTreeSet<String>,
    filter: Option<&'a RowFilter>,
}

/// One item's export, on its way to the writer.
struct Exported {
    id: String,
    stem: String,
    /// Its manifest's provenance columns.
    provenance: BTreeMap<String, String>,
    export: Result<sparc3d_formats::ItemExport>,
}

/// Writes every wanted ok item's files under `dir`; an item that fails is named on stderr and
/// the rest go on. Errors only when a shard cannot be read or a file cannot be written.
///
/// Items are computed in parallel batches of twice the pool's threads (so a slow item does
/// not leave the other threads idle for long) while one writer thread writes the previous
/// batches' files in manifest order; at most two batches' files are in memory.
fn write_items(
    job: &Job,
    consumer: Consumer,
    frame: Frame,
    wanted: &Chosen,
    dir: &Path,
) -> Result<Written> {
    let at_once = 2 * rayon::current_num_threads().max(1);
    let (send, receive) = std::sync::mpsc::sync_channel::<Exported>(at_once);
    std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> Result<Written> {
            let mut out = Written::default();
            for item in receive {
                record_item(dir, item, &mut out)?;
            }
            Ok(out)
        });
        let computed = compute_items(job, consumer, frame, wanted, at_once, &send);
        drop(send);
        let written = writer
            .join()
            .unwrap_or_else(|_| Err(anyhow::anyhow!("the export's writer thread panicked")));
        // A writer error (a file that cannot be written) is the cause when both failed.
        let mut written = written?;
        written.filtered_out = computed?;
        Ok(written)
    })
}

/// Computes the wanted ok items' exports in batches of `at_once` and sends them in manifest
/// order while a reader thread streams the next rows from the shards (only the columns the
/// consumer reads; each finished shard's file hashed against its record as it is read);
/// stops early when the writer has stopped. Returns how many ok items `--where` left out.
fn compute_items(
    job: &Job,
    consumer: Consumer,
    frame: Frame,
    wanted: &Chosen,
    at_once: usize,
    send: &std::sync::mpsc::SyncSender<Exported>,
) -> Result<u64> {
    let (rows_in, rows_out) = std::sync::mpsc::sync_channel::<ShardRow>(at_once);
    std::thread::scope(|scope| {
        let reader = scope.spawn(move || read_wanted_rows(job, consumer, wanted, &rows_in));
        let names = ExportNames::for_job(job.file.items);
        let mut rows = rows_out.iter().peekable();
        'batches: while rows.peek().is_some() {
            let batch: Vec<ShardRow> = rows.by_ref().take(at_once).collect();
            let exports: Vec<Exported> = batch
                .par_iter()
                .map(|row| export_item(job, row, consumer, frame, &names))
                .collect();
            for item in exports {
                if send.send(item).is_err() {
                    break 'batches; // the writer stopped: its error is reported
                }
            }
        }
        // The reader stops at its next row once nobody receives them.
        drop(rows);
        drop(rows_out);
        reader
            .join()
            .unwrap_or_else(|_| Err(anyhow::anyhow!("the export's shard reader panicked")))
    })
}

/// Sends the wanted ok rows of the job's shards, in manifest order, until the receiver is
/// gone, and returns how many ok rows `--where` left out; a shard that cannot be read, or
/// whose file does not match its record, is an error.
fn read_wanted_rows(
    job: &Job,
    consumer: Consumer,
    chosen: &Chosen,
    send: &std::sync::mpsc::SyncSender<ShardRow>,
) -> Result<u64> {
    let wanted = chosen.ids;
    let mut shards = BTreeSet::new();
    for item in job.items() {
        let item = item?;
        if wanted.is_empty() || wanted.contains(item.record.id.as_str()) {
            shards.insert(item.shard);
        }
    }
    let columns = if consumer.reads_samples() {
        Columns::All
    } else {
        Columns::WithoutSamples
    };
    let mut receiver_gone = false;
    let mut filtered_out = 0;
    for shard in shards {
        for_each_shard_row(job, shard, Check::Full, columns, |mut row| {
            let mut keep =
                (wanted.is_empty() || wanted.contains(row.id.as_str())) && row.tensors.is_some();
            if let (true, Some(filter)) = (keep, chosen.filter) {
                let item = job.item(row.item_index)?;
                keep = filter.keeps(&mut row, item.as_ref())?;
                filtered_out += u64::from(!keep);
            }
            if keep && !receiver_gone {
                receiver_gone = send.send(row).is_err();
            }
            Ok(())
        })
        .with_context(|| format!("reading shard {shard}"))?;
        if receiver_gone {
            break;
        }
    }
    Ok(filtered_out)
}

/// One row's export, named and with its provenance.
fn export_item(
    job: &Job,
    row: &ShardRow,
    consumer: Consumer,
    frame: Frame,
    names: &ExportNames,
) -> Exported {
    let stem = names.stem(row.item_index, &row.id);
    let export = export_row(job, row, consumer, frame, &stem);
    let provenance = job
        .item(row.item_index)
        .ok()
        .flatten()
        .map(|i| i.record.extra)
        .unwrap_or_default();
    Exported {
        id: row.id.clone(),
        stem,
        provenance,
        export,
    }
}

/// Writes one item's files and lists it, or counts it as left out, or names it as failed.
fn record_item(dir: &Path, item: Exported, out: &mut Written) -> Result<()> {
    match item.export {
        Ok(export) => {
            for f in &export.files {
                write_file(dir, f)?;
            }
            if let Some(note) = export.note {
                out.noted.push((item.id.clone(), note));
            }
            out.listed.push(Listed {
                id: item.id,
                stem: item.stem,
                files: export.files.into_iter().map(|f| f.path).collect(),
                columns: export.listing,
                provenance: item.provenance,
            });
        }
        Err(e) => match e.downcast_ref::<sparc3d_formats::Error>() {
            Some(sparc3d_formats::Error::LeftOut(why)) => {
                out.left_out.push((item.id, why.clone()));
            }
            _ => {
                eprintln!("error: item {:?}: {e:#}", item.id);
                out.failed.push((item.id, format!("{e:#}")));
            }
        },
    }
    Ok(())
}

/// The files of one item.
fn export_row(
    job: &Job,
    row: &ShardRow,
    consumer: Consumer,
    frame: Frame,
    stem: &str,
) -> Result<sparc3d_formats::ItemExport> {
    let cubes = row.cubes()?;
    let stored = row.tensors.as_ref().and_then(|t| t.samples.as_ref());
    let samples = match stored.filter(|_| consumer.reads_samples()) {
        Some(t) => Some(t.to_samples()?),
        None => None,
    };
    let stored = row.tensors.as_ref().and_then(|t| t.attributes.as_ref());
    let attributes = match stored.filter(|_| consumer.reads_attributes()) {
        Some(t) => Some(t.to_attributes()?),
        None => None,
    };
    let stored_renders = row.tensors.as_ref().and_then(|t| t.renders.as_ref());
    let pngs: Vec<&[u8]> = stored_renders
        .map(|r| r.views.iter().map(|v| v.png.as_slice()).collect())
        .unwrap_or_default();
    let config = &job.file.config;
    // The manifest's sha256, else the one the row recorded of the bytes it converted; the id
    // where it covers the files the mesh names as well (colour variants of one mesh file).
    let frozen = job.item(row.item_index).ok().flatten();
    let source_sha256 = frozen
        .as_ref()
        .and_then(|i| i.record.sha256.as_deref())
        .or(row.source_sha256.as_deref());
    let source_key = match source_sha256 {
        Some(sha) if names_files_of(&row.id, sha) => Some(row.id.as_str()),
        other => other,
    };
    let item = Item {
        id: &row.id,
        item_index: row.item_index,
        stem,
        source_key,
        cubes: &cubes,
        samples: samples.as_ref().map(|s| StoredSamples {
            samples: s,
            params: &config.samples.params,
        }),
        attributes: attributes.as_ref(),
        renders: stored_renders.map(|r| sparc3d_formats::renders::StoredRenders {
            pngs: &pngs,
            transforms: &r.transforms,
        }),
        object_span: config.params.span(),
        output_span: config.params.output_span,
        frame,
    };
    Ok(consumer.files(&item)?)
}

/// Writes the consumer's listing files (its `{split}.json`, `metadata.csv`, …).
fn write_listing(consumer: Consumer, listed: &[Listed], root: &Path, dir: &Path) -> Result<()> {
    for f in consumer.listing(listed, root)? {
        write_file(dir, &f)?;
    }
    Ok(())
}

/// Writes [`EXPORT_RECORD`]: the job, consumer, frame, and each item's files (and the failures).
fn write_record(
    job: &Job,
    consumer: Consumer,
    frame: Frame,
    written: &Written,
    dir: &Path,
    filter: Option<&RowFilter>,
) -> Result<()> {
    let items: Vec<serde_json::Value> = written
        .listed
        .iter()
        .map(|l| {
            let mut item = serde_json::json!({
                "id": l.id,
                "stem": l.stem,
                "files": l.files.iter().map(|p| p.to_string_lossy()).collect::<Vec<_>>(),
            });
            if !l.provenance.is_empty() {
                item["manifest"] = serde_json::json!(l.provenance);
            }
            item
        })
        .collect();
    let listed = |rows: &[(String, String)], key: &str| -> Vec<serde_json::Value> {
        rows.iter()
            .map(|(id, why)| serde_json::json!({"id": id, key: why}))
            .collect()
    };
    let noted: Vec<(String, String)> = written
        .noted
        .iter()
        .map(|(id, note)| (id.clone(), note.to_string()))
        .collect();
    let mut record = serde_json::json!({
        "job": job.layout.root.to_string_lossy(),
        "fingerprint": job.fingerprint(),
        "format": consumer.name(),
        "frame": frame.name(),
        "items": items,
        "noted": listed(&noted, "note"),
        "left_out": listed(&written.left_out, "why"),
        "failed": listed(&written.failed, "error"),
    });
    if let Some(f) = filter {
        record["where"] = serde_json::json!(f.text);
    }
    let bytes = serde_json::to_vec_pretty(&record)?;
    write_file(
        dir,
        &ExportFile {
            path: EXPORT_RECORD.into(),
            bytes,
        },
    )
}

/// Writes one file under `dir` (its parent folders created) and fsyncs it.
fn write_file(dir: &Path, file: &ExportFile) -> Result<()> {
    let path = dir.join(&file.path);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&path)?;
        f.write_all(&file.bytes)?;
        f.sync_all()
    })()
    .with_context(|| format!("writing {}", path.display()))
}

/// An error when `out` exists and is neither empty nor an earlier export (no
/// [`EXPORT_RECORD`]): such a folder is never replaced.
fn refuse_a_folder_that_is_not_an_export(out: &Path) -> Result<()> {
    let mut entries = match std::fs::read_dir(out) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("reading {}", out.display())),
    };
    if entries.next().is_none() || out.join(EXPORT_RECORD).is_file() {
        return Ok(());
    }
    bail!(
        "{} holds files and is not an export (no {EXPORT_RECORD}); not overwritten: export \
         into a new or empty folder",
        out.display()
    )
}

/// The folder an export is built in, beside its destination: `.NAME.partial-PID`.
struct Staging {
    dir: PathBuf,
}

impl Staging {
    /// Creates the staging folder for `out` (removing one a killed export left).
    fn create(out: &Path) -> Result<Self> {
        let dir = sibling(out, "partial")?;
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .with_context(|| format!("removing a stale {}", dir.display()))?;
        }
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self { dir })
    }

    /// Removes the staging folder (after an error).
    fn discard(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }

    /// Moves the finished export to `out`: swapped with an earlier export there in one step
    /// (which is then removed from the staging folder's name), or where the file system
    /// cannot, the earlier one moved aside first and removed after; `out` is always a whole
    /// export. An earlier export that cannot be removed (read-only) does not fail the export,
    /// which is complete and in place: what is left and where is handed back to be said.
    fn move_to(self, out: &Path) -> Result<Option<String>> {
        sync_tree(&self.dir)?;
        let old = sibling(out, "old")?;
        let replaced = out.exists();
        if replaced && super::export_debris::exchange(&self.dir, out)? {
            sync_parent(out)?;
            return Ok(remove_earlier(&self.dir, out));
        }
        if replaced {
            if old.exists() {
                std::fs::remove_dir_all(&old)
                    .with_context(|| format!("removing a stale {}", old.display()))?;
            }
            std::fs::rename(out, &old)
                .with_context(|| format!("moving {} aside to {}", out.display(), old.display()))?;
        }
        std::fs::rename(&self.dir, out)
            .with_context(|| format!("moving {} to {}", self.dir.display(), out.display()))?;
        sync_parent(out)?;
        Ok(replaced.then(|| remove_earlier(&old, out)).flatten())
    }
}

/// fsyncs the folder holding `out`, so that its new name is durable.
fn sync_parent(out: &Path) -> Result<()> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        sparc3d_workers::fsutil::sync_dir(parent)?;
    }
    Ok(())
}

/// Removes the earlier export of `out`, moved to `earlier`; `None` when it is gone, else what
/// is left there and why (the new export is in place either way).
fn remove_earlier(earlier: &Path, out: &Path) -> Option<String> {
    let err = std::fs::remove_dir_all(earlier).err()?;
    Some(format!(
        "the export in {} is complete; the earlier export it replaced could not be removed \
         from {} ({err}): remove it by hand",
        out.display(),
        earlier.display()
    ))
}

/// `.NAME.KIND-PID` beside `out`.
fn sibling(out: &Path, kind: &str) -> Result<PathBuf> {
    let Some(name) = out.file_name() else {
        bail!("--out {}: not a folder name", out.display());
    };
    let name = format!(".{}.{kind}-{}", name.to_string_lossy(), std::process::id());
    Ok(out.with_file_name(name))
}

/// fsyncs every folder under `dir` (the files were fsynced as written).
fn sync_tree(dir: &Path) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let entry = entry.with_context(|| format!("reading {}", dir.display()))?;
        if entry.file_type().map(|t| t.is_dir()).unwrap_or(false) {
            sync_tree(&entry.path())?;
        }
    }
    Ok(sparc3d_workers::fsutil::sync_dir(dir)?)
}
