//! `--resolution`, `--shard-size`, `--config` and `--for`: the flags that make a job's config
//! (`init`, `run --job`); the config itself is built from them by `job/config.rs`.

use crate::util::units::with_default;
use sparc3d_formats::preset::Preset;
use sparc3d_schema::JobConfig;
use std::path::PathBuf;

/// The flags that make a job's config (shared by `init` and `run --job`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ConfigArgs {
    /// `--resolution N`.
    #[command(flatten)]
    pub resolution: crate::flags::resolution::ResolutionArg,
    /// Items per shard (overrides the config file).
    #[arg(long, help = with_default(
        "Items per shard (overrides the config file)",
        JobConfig::default().shard_size,
    ))]
    pub shard_size: Option<u32>,
    /// Config file (TOML) with any of the job config's keys.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Make the job for a consumer (docs/FORMAT.md, "Presets"): each preset with what it
    /// sets, from the consumers' table (`Preset::help`). The config file's keys and the
    /// other flags win over it; job.json records it as `preset`.
    #[arg(long = "for", value_name = "CONSUMER", help = format!(
        "Make the job for a consumer (docs/FORMAT.md, \"Presets\"): {}. The config file's \
         keys and the other flags win over it; job.json records it as `preset`",
        Preset::help()
    ))]
    pub preset: Option<String>,
    /// Render each item's condition views with the conversion (`[renders] enabled = true`,
    /// docs/RENDERS.md), with the `--for` consumer's recipe (each preset's views, from the
    /// consumers' table: `Preset::renders_help`) unless the config file sets one.
    #[arg(long, help = format!(
        "Render each item's condition views with the conversion (`[renders] enabled = true`, \
         docs/RENDERS.md), with the `--for` consumer's recipe ({}) unless the config file \
         sets one",
        Preset::renders_help()
    ))]
    pub renders: bool,
}

impl ConfigArgs {
    /// Whether any flag was given.
    pub fn any(&self) -> bool {
        self.resolution.given.is_some()
            || self.shard_size.is_some()
            || self.config.is_some()
            || self.preset.is_some()
            || self.renders
    }
}
