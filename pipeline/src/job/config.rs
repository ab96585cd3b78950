//! A job's config from the flags (`--for`'s preset, the `--config` file's keys over it, the
//! typed flags over both), and the refusal of a config that differs from an existing job's,
//! naming the keys.

use crate::flags::config::ConfigArgs;
use anyhow::{bail, Context, Result};
use sparc3d_formats::preset::Preset;
use sparc3d_schema::JobConfig;
use std::path::Path;

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
    // A span of the file's wins over the preset's output span, as its other keys do (the two
    // exclude each other).
    let own_span = file.pointer("/params/object_span").is_some();
    merge_json(&mut overrides, file);
    if let Some(params) = overrides.get_mut("params").and_then(|p| p.as_object_mut()) {
        if own_span {
            params.remove("output_span");
        }
    }
    let mut config = JobConfig::overlaid(&overrides).context("invalid job config")?;
    if let Some(r) = args.resolution.given {
        config.params.resolution = r;
    }
    if let Some(s) = args.shard_size {
        config.shard_size = s;
    }
    if args.renders {
        config.renders.enabled = true;
    }
    config.preset = preset.map(|p| p.name());
    // Its errors already begin "invalid job config:".
    config.validate()?;
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
    match preset.misfit(&config.params) {
        Some(line) => lines.push(line),
        None => lines.extend(check.required),
    }
    lines.extend(check.warnings);
    for line in lines {
        eprintln!("warning: --for {}: {line}", preset.name());
    }
}

/// Refuses a config that differs from the one `existing` was created with, naming the keys.
pub fn check_same_config(existing: &sparc3d_workers::Job, config: &JobConfig) -> Result<()> {
    check_same_config_of(existing, config, &existing.layout.root)
}

/// [`check_same_config`], naming the job `shown` in messages (a job URL whose files are
/// checked in a local copy).
pub(super) fn check_same_config_of(
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
