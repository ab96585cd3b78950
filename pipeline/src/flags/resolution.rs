//! `--resolution N`: the one grid-resolution flag of every command that takes one (`init`,
//! `run --job`, `convert`, `preview`, `eval`, `bench-one`; `bench` takes a list with the same
//! default). Its default is the library's (`sparcubes::Params::default()`); where a job or a
//! config file has its own, the flag only overrides it when given.

use crate::util::units::with_default;

/// The library's default grid resolution.
pub fn default_resolution() -> u32 {
    sparcubes::Params::default().resolution
}

/// `--resolution N`.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct ResolutionArg {
    /// Grid resolution N, cells per axis (`init`, `run --job`: overrides the config file).
    #[arg(long = "resolution", value_name = "N", help = with_default(
        "Grid resolution N, cells per axis (init, run --job: overrides the config file)",
        default_resolution(),
    ))]
    pub given: Option<u32>,
}

impl ResolutionArg {
    /// The resolution given, or the library's default.
    pub fn get(&self) -> u32 {
        self.or(default_resolution())
    }

    /// The resolution given, or `fallback` (a job's, an item's).
    pub fn or(&self, fallback: u32) -> u32 {
        self.given.unwrap_or(fallback)
    }
}
