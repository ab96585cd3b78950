//! `sparc3d init JOB --manifest M [--resolution N] [--shard-size S] [--config job.toml]`:
//! freezes the manifest into the job folder, gives every item its shard once, and writes the
//! config with its fingerprint. Re-running with another config is refused, naming the keys.

use crate::manifest_io;
use crate::units::with_default;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use sparc3d_schema::{FrozenItem, JobConfig, JobFile, JobLayout, ManifestRecord};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d init`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder to create.
    pub job: PathBuf,
    /// Manifest (.csv, .jsonl or .parquet with a path column).
    #[arg(long)]
    pub manifest: PathBuf,
    #[command(flatten)]
    pub config: ConfigArgs,
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
}

impl ConfigArgs {
    /// Whether any flag was given.
    pub fn any(&self) -> bool {
        self.resolution.given.is_some() || self.shard_size.is_some() || self.config.is_some()
    }
}

/// The job config from defaults, the config file and the flags (typed, set over the file's).
pub fn build_config(args: &ConfigArgs) -> Result<JobConfig> {
    let mut overrides = serde_json::json!({});
    if let Some(path) = &args.config {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading config {}", path.display()))?;
        let t: toml::Value =
            toml::from_str(&text).with_context(|| format!("parsing config {}", path.display()))?;
        overrides = serde_json::to_value(t)?;
    }
    let mut config = JobConfig::overlaid(&overrides).context("invalid job config")?;
    if let Some(r) = args.resolution.given {
        config.params.resolution = r;
    }
    if let Some(s) = args.shard_size {
        config.shard_size = s;
    }
    config.validate().context("invalid job config")?;
    Ok(config)
}

fn freeze(records: Vec<manifest_io::RawRecord>, shard_size: u32) -> Result<Vec<FrozenItem>> {
    let with_ids: Vec<Result<ManifestRecord>> = records
        .into_par_iter()
        .map(|r| {
            let (id, sha) = match (r.id, r.sha256) {
                (Some(id), sha) => (id, sha),
                (None, Some(sha)) => (sha.clone(), Some(sha)),
                (None, None) => {
                    let sha = sparc3d_workers::fsutil::file_sha256(std::path::Path::new(&r.uri))
                        .with_context(|| format!("hashing {} for its id", r.uri))?;
                    (sha.clone(), Some(sha))
                }
            };
            Ok(ManifestRecord {
                id,
                uri: r.uri,
                sha256: sha,
                format: r.format,
            })
        })
        .collect();
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut items = Vec::with_capacity(with_ids.len());
    let mut dups = Vec::new();
    for (i, rec) in with_ids.into_iter().enumerate() {
        let rec = rec?;
        if let Some(first) = seen.get(&rec.id) {
            dups.push(format!("{} (rows {} and {})", rec.id, first + 1, i + 1));
            continue;
        }
        seen.insert(rec.id.clone(), i);
        let index = items.len() as u64;
        items.push(FrozenItem {
            index,
            shard: index / shard_size.max(1) as u64,
            record: rec,
        });
    }
    if !dups.is_empty() {
        bail!(
            "the manifest has {} duplicate ids, e.g. {}; ids must be unique",
            dups.len(),
            dups.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
        );
    }
    Ok(items)
}

/// Runs `sparc3d init`.
pub fn run(args: Args) -> Result<ExitCode> {
    let config = build_config(&args.config)?;
    let records = manifest_io::read(&args.manifest)?;
    if records.is_empty() {
        bail!("{}: the manifest is empty", args.manifest.display());
    }
    create(&args.job, records, config)?;
    Ok(ExitCode::SUCCESS)
}

/// Refuses a config that differs from the one `existing` was created with, naming the keys.
pub fn check_same_config(existing: &sparc3d_workers::Job, config: &JobConfig) -> Result<()> {
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
                    existing.layout.root.display()
                )
            })
            .unwrap_or_default();
        bail!(
            "{} is already initialised with a different config; differing keys: {} \
             (use a new job folder, or the same config){hint}",
            existing.layout.root.display(),
            keys.join(", ")
        );
    }
    Ok(())
}

/// Creates the job folder `job` from manifest records and a config: frozen manifest, shard of
/// every item, job file. An existing job with the same config and manifest is left as it is;
/// one with another config or manifest is refused.
pub fn create(job: &Path, records: Vec<manifest_io::RawRecord>, config: JobConfig) -> Result<()> {
    let layout = JobLayout::new(job);
    let items = freeze(records, config.shard_size)?;
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
        let existing = sparc3d_workers::Job::open(&layout.root)?;
        check_same_config(&existing, &config)?;
        if existing.file.manifest_sha256 != manifest_sha256 {
            bail!(
                "{} is already initialised with a different manifest ({} items, now {}); \
                 shard assignment never changes: use a new job folder",
                layout.root.display(),
                existing.file.items,
                items.len()
            );
        }
        eprintln!(
            "{} is already initialised with this config and manifest; nothing to do",
            layout.root.display()
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
    sparc3d_workers::fsutil::write_atomic(
        &layout.job_file(),
        &serde_json::to_vec_pretty(&file)?,
        "writing job file",
    )?;
    eprintln!(
        "initialised {}: {} items in {} shards, fingerprint {}",
        layout.root.display(),
        file.items,
        shards,
        &file.fingerprint[..12]
    );
    Ok(())
}
