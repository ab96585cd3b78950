//! `sparc3d init JOB --manifest M [--for CONSUMER] [--resolution N] [--shard-size S]
//! [--config job.toml] [--path-column NAME] [--where FILTER]`: freezes the manifest into the job folder (`sparc3d_manifests::freeze`), gives every
//! item its shard once, and writes the config with its fingerprint. Re-running with another
//! config is refused, naming the keys; a job whose files were edited since is refused too.

use crate::units::with_default;
use anyhow::{bail, Context, Result};
use sparc3d_formats::preset::Preset;
use sparc3d_manifests::filter::Filter;
use sparc3d_manifests::table as manifest_io;
use sparc3d_manifests::RawRecord;
use sparc3d_schema::{JobConfig, JobFile, JobLayout};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d init`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder to create, or a bucket prefix (s3://, gs://, az://) to make the job's home.
    pub job: PathBuf,
    /// Manifest (.csv, .jsonl or .parquet with a path column).
    #[arg(long)]
    pub manifest: PathBuf,
    #[command(flatten)]
    pub source: SourceArgs,
    #[command(flatten)]
    pub config: ConfigArgs,
}

/// How a manifest's rows are read (shared by `init`, `run --job` and `add`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SourceArgs {
    /// The manifest's column of local paths, when it has several path-like columns that the
    /// rule cannot tell apart (docs/RELIABILITY.md, "Manifests").
    #[arg(long, value_name = "NAME")]
    pub path_column: Option<String>,
    /// Keep only the manifest rows that pass FILTER, e.g. `license in (cc-by, cc0)` or
    /// `source = objaverse` (conditions joined by `and`; docs/FORMAT.md, "Provenance
    /// columns"); says how many it left out.
    #[arg(long = "where", value_name = "FILTER")]
    pub filter: Option<String>,
}

/// The flags that make a job's config (shared by `init` and `run --job`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ConfigArgs {
    /// `--resolution N`.
    #[command(flatten)]
    pub resolution: crate::resolution_arg::ResolutionArg,
    /// Items per shard (overrides the config file).
    #[arg(long, help = with_default(
        "Items per shard (overrides the config file)",
        JobConfig::default().shard_size,
    ))]
    pub shard_size: Option<u32>,
    /// Config file (TOML) with any of the job config's keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Make the job for a consumer (docs/FORMAT.md, "Presets"): `trellis2@G` (TRELLIS.2's
    /// grid of G exactly), `direct3d-s2[@N]` (its span; N its resolution), `hunyuan3d-2.1`,
    /// `dora`, `step1x-3d`, `triposg`, `vecset-npz` (samples on). The config file's keys and
    /// the other flags win over it; job.json records it as `preset`.
    #[arg(long = "for", value_name = "CONSUMER")]
    pub preset: Option<String>,
}

impl ConfigArgs {
    /// Whether any flag was given.
    pub fn any(&self) -> bool {
        self.resolution.given.is_some()
            || self.shard_size.is_some()
            || self.config.is_some()
            || self.preset.is_some()
    }
}

/// The job config from defaults, the preset (`--for`, else the config file's `preset` key),
/// the config file's keys over it, and the flags (typed, set over the file's). Warns when the
/// result does not fit the preset's consumer (a flag or key that overrode what it needs).
pub fn build_config(args: &ConfigArgs) -> Result<JobConfig> {
    let mut file = match &args.config {
        Some(path) => config_file(path)?,
        None => serde_json::json!({}),
    };
    let in_file = take_preset(&mut file, args.config.as_deref())?;
    let preset = args
        .preset
        .as_deref()
        .or(in_file.as_deref())
        .map(Preset::parse)
        .transpose()?;
    let mut overrides = preset.map_or(serde_json::json!({}), |p| p.settings().overrides());
    merge_json(&mut overrides, file);
    let mut config = JobConfig::overlaid(&overrides).context("invalid job config")?;
    if let Some(r) = args.resolution.given {
        config.params.resolution = r;
    }
    if let Some(s) = args.shard_size {
        config.shard_size = s;
    }
    config.preset = preset.map(|p| p.name());
    config.validate().context("invalid job config")?;
    if let Some(p) = preset {
        warn_misfit(p, &config);
    }
    Ok(config)
}

/// A config file's keys as a JSON object.
fn config_file(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading config {}", path.display()))?;
    let t: toml::Value =
        toml::from_str(&text).with_context(|| format!("parsing config {}", path.display()))?;
    Ok(serde_json::to_value(t)?)
}

/// Takes the `preset` key out of a config file's keys (`preset = "trellis2@512"`, what
/// `--for` gives); refuses one that is not a string.
fn take_preset(file: &mut serde_json::Value, path: Option<&Path>) -> Result<Option<String>> {
    let Some(value) = file.as_object_mut().and_then(|m| m.remove("preset")) else {
        return Ok(None);
    };
    match value {
        serde_json::Value::String(text) => Ok(Some(text)),
        other => bail!(
            "{}: preset = {other}: a preset is a string such as \"trellis2@512\" ({})",
            path.map_or("config".into(), |p| p.display().to_string()),
            Preset::forms()
        ),
    }
}

/// `over` merged into `base`: tables key by key, any other value replaced.
fn merge_json(base: &mut serde_json::Value, over: serde_json::Value) {
    match (base, over) {
        (serde_json::Value::Object(b), serde_json::Value::Object(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge_json(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// Says what a job made with `preset` lacks for its consumer, as the export would: a setting
/// the config file or a flag changed from the preset's (they win), or samples too few.
fn warn_misfit(preset: Preset, config: &JobConfig) {
    let consumer = preset.consumer;
    let samples = &config.samples;
    let mut lines = consumer.missing(samples.enabled.then_some(&samples.params));
    let check = consumer.check(&config.params, sparc3d_formats::Frame::Consumer);
    lines.extend(check.required);
    lines.extend(check.warnings);
    for line in lines {
        eprintln!("warning: --for {}: {line}", preset.name());
    }
}

/// When the job's frozen copy is not what `init` froze (its sha256 is not the one `job.json`
/// recorded): the first line where it differs from `text`, the manifest given to `init` again
/// frozen now, for the error that refuses the job. With the manifest the job was made from,
/// that is the edited line; with another, the first line where the two differ.
fn frozen_copy_differs(
    layout: &JobLayout,
    shown: &Path,
    text: &str,
    sha256: &str,
) -> Option<String> {
    let file: JobFile = sparc3d_workers::fsutil::read_json(&layout.job_file()).ok()?;
    let frozen = std::fs::read_to_string(layout.manifest()).ok()?;
    if sparc3d_workers::fsutil::bytes_sha256(frozen.as_bytes()) == file.manifest_sha256 {
        return None; // the frozen copy is as `init` wrote it: something else was edited
    }
    let first = frozen
        .lines()
        .zip(text.lines())
        .enumerate()
        .find(|(_, (a, b))| a != b);
    let differs = |theirs: &str| match first {
        Some((n, (now, meant))) => format!("line {}: {now}, where {theirs} {meant}", n + 1),
        None => format!(
            "{} lines, where {theirs} {}",
            frozen.lines().count(),
            text.lines().count()
        ),
    };
    let copy = shown.join("manifest.jsonl");
    Some(if file.manifest_sha256 == sha256 {
        format!(
            "this manifest is the one {} was made from, but its frozen copy {} was edited \
             since: {}",
            shown.display(),
            copy.display(),
            differs("it froze")
        )
    } else {
        format!(
            "its frozen copy {} was edited since `init` (and this manifest is not the one {} \
             was made from); the frozen copy first differs from this manifest at {}",
            copy.display(),
            shown.display(),
            differs("this manifest freezes to")
        )
    })
}

/// `e`, a job's refusal, naming the job `shown` rather than the folder `root` it was checked
/// in (a bucket job is checked in a local copy).
fn named_as(
    e: sparc3d_workers::WorkerError,
    root: &Path,
    shown: &Path,
) -> sparc3d_workers::WorkerError {
    use sparc3d_workers::WorkerError;
    match e {
        WorkerError::EditedJob { problems, .. } => WorkerError::EditedJob {
            root: shown.to_path_buf(),
            problems,
        },
        WorkerError::BadFile { path, reason } => WorkerError::BadFile {
            path: path
                .strip_prefix(root)
                .map_or_else(|_| path.clone(), |name| shown.join(name)),
            reason,
        },
        other => other,
    }
}

/// Runs `sparc3d init`.
pub fn run(args: Args) -> Result<ExitCode> {
    let config = build_config(&args.config)?;
    let records = read_manifest(&args.manifest, &args.source)?;
    match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => create(&dir, records, config)?,
        sparc3d_bucket::JobHome::Bucket(url) => crate::bucket_home::init(&url, records, config)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// Reads a manifest's rows for a job, saying which column its paths came from, which
/// provenance columns it keeps and how many rows `--where` left out; an empty manifest (or
/// one that `--where` empties) is refused.
pub fn read_manifest(path: &Path, source: &SourceArgs) -> Result<Vec<RawRecord>> {
    let manifest = manifest_io::read(path, source.path_column.as_deref())?;
    if manifest.records.is_empty() {
        bail!("{}: the manifest is empty", path.display());
    }
    eprintln!(
        "{}: {} rows, paths from column {} ({})",
        path.display(),
        manifest.records.len(),
        manifest.path_column.name,
        manifest.path_column.why
    );
    if let Some(first) = manifest.records.first().filter(|r| !r.extra.is_empty()) {
        let names: Vec<&str> = first.extra.keys().map(String::as_str).collect();
        eprintln!(
            "{}: provenance columns kept with every item: {}",
            path.display(),
            names.join(", ")
        );
    }
    select(manifest.records, source, path)
}

/// The rows of `input` (a manifest or a folder) that pass `--where`, saying how many it left
/// out; all of them without `--where`. Refused when none passes.
pub fn select(
    records: Vec<RawRecord>,
    source: &SourceArgs,
    input: &Path,
) -> Result<Vec<RawRecord>> {
    let Some(text) = &source.filter else {
        return Ok(records);
    };
    let (kept, left_out) = Filter::parse(text)?.apply(records)?;
    eprintln!(
        "{}: --where {text}: {} rows kept, {left_out} left out",
        input.display(),
        kept.len()
    );
    if kept.is_empty() {
        bail!("{}: no row passes --where {text}", input.display());
    }
    Ok(kept)
}

/// Refuses a config that differs from the one `existing` was created with, naming the keys.
pub fn check_same_config(existing: &sparc3d_workers::Job, config: &JobConfig) -> Result<()> {
    check_same_config_of(existing, config, &existing.layout.root)
}

/// [`check_same_config`], naming the job `shown` in messages (a job URL whose files are
/// checked in a local copy).
fn check_same_config_of(
    existing: &sparc3d_workers::Job,
    config: &JobConfig,
    shown: &Path,
) -> Result<()> {
    let keys = existing.file.config.diff_keys(config)?;
    if !keys.is_empty() {
        // Jobs made before a rule became the default stored no key for it and convert without
        // it; the same command line now asks for it, so say how to resume.
        let stored = &existing.file.config.params;
        let off = [
            ("inside_test", "the inside test", stored.inside_test),
            (
                "seal_openings",
                "the sealing of small openings",
                stored.seal_openings,
            ),
        ];
        let hint = off
            .iter()
            .find(|(key, _, on)| !on && keys.iter().any(|k| *k == format!("params.{key}")))
            .map(|(key, what, _)| {
                format!(
                    "; this job converts without {what} (the default before it was switched \
                     on): resume it with `sparc3d run {}` alone, or give the command a config \
                     with `{key} = false` under [params]",
                    shown.display()
                )
            })
            .unwrap_or_default();
        bail!(
            "{} is already initialised with a different config; differing keys: {} \
             (use a new job folder, or the same config){hint}",
            shown.display(),
            keys.join(", ")
        );
    }
    Ok(())
}

/// Creates the job folder `job` from manifest records and a config: frozen manifest, shard of
/// every item, job file. An existing job with the same config and manifest is left as it is;
/// one with another config or manifest is refused.
pub fn create(job: &Path, records: Vec<RawRecord>, config: JobConfig) -> Result<()> {
    create_named(job, job, records, config)
}

/// [`create`] in the folder `job`, naming the job `shown` in messages (`init` to a bucket
/// makes the job in a local folder first).
pub fn create_named(
    job: &Path,
    shown: &Path,
    records: Vec<RawRecord>,
    config: JobConfig,
) -> Result<()> {
    let layout = JobLayout::new(job);
    let items = sparc3d_manifests::freeze::freeze(records, config.shard_size)?;
    let mut text = String::new();
    for it in &items {
        text.push_str(&serde_json::to_string(it)?);
        text.push('\n');
    }
    let manifest_sha256 = {
        use sha2::{Digest, Sha256};
        sparc3d_schema::config::hex(&Sha256::digest(text.as_bytes()))
    };
    if layout.job_file().exists() {
        let existing = sparc3d_workers::Job::open(&layout.root).map_err(|e| {
            let e = named_as(e, &layout.root, shown);
            match frozen_copy_differs(&layout, shown, &text, &manifest_sha256) {
                Some(line) => anyhow::Error::new(e).context(line),
                None => e.into(),
            }
        })?;
        check_same_config_of(&existing, &config, shown)?;
        if existing.file.manifest_sha256 != manifest_sha256 {
            bail!(
                "{} is already initialised with a different manifest ({} items, now {}); \
                 shard assignment never changes: use a new job folder",
                shown.display(),
                existing.file.items,
                items.len()
            );
        }
        eprintln!(
            "{} is already initialised with this config and manifest; nothing to do",
            shown.display()
        );
        return Ok(());
    }
    sparc3d_workers::fsutil::create_dir(&layout.shards_dir())?;
    sparc3d_workers::fsutil::create_dir(&layout.state_dir())?;
    sparc3d_workers::fsutil::write_atomic(
        &layout.manifest(),
        text.as_bytes(),
        "freezing manifest",
    )?;
    let shards = (items.len() as u64).div_ceil(config.shard_size.max(1) as u64);
    let file = JobFile {
        schema_version: sparc3d_schema::SCHEMA_VERSION,
        tool_version: sparc3d_schema::TOOL_VERSION.into(),
        fingerprint: config.fingerprint()?,
        config,
        items: items.len() as u64,
        shards,
        manifest_sha256,
    };
    // job.json last: its presence is what makes the folder a job.
    sparc3d_workers::job::write_job_file(&layout, &file)?;
    eprintln!(
        "initialised {}: {} items in {} shards, fingerprint {}{}",
        shown.display(),
        file.items,
        shards,
        &file.fingerprint[..12],
        file.config
            .preset
            .as_ref()
            .map(|p| format!(", made for {p}"))
            .unwrap_or_default()
    );
    Ok(())
}
