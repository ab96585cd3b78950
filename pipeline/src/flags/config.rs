//! `--resolution`, `--shard-size`, `--config` and `--for`: the flags that make a job's config
//! (`init`, `run --job`); the config itself is built from them by `job/config.rs`.

use crate::util::units::with_default;
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
    /// Make the job for a consumer (docs/FORMAT.md, "Presets"): `trellis2@G` (TRELLIS.2's
    /// grid of G exactly), `direct3d-s2[@N]` (its span; N its resolution), `hunyuan3d-2.1`,
    /// `dora`, `step1x-3d`, `triposg`, `vecset-npz` (samples on). The config file's keys and
    /// the other flags win over it; job.json records it as `preset`.
    #[arg(long = "for", value_name = "CONSUMER")]
    pub preset: Option<String>,
    /// Render each item's condition views with the conversion (`[renders] enabled = true`,
    /// docs/RENDERS.md), with the `--for` consumer's recipe (TRELLIS.2's 16 views of 1024²,
    /// Hunyuan3D-2.1's 24 of 512², Step1X-3D's 20 of 512²) unless the config file sets one.
    #[arg(long)]
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
