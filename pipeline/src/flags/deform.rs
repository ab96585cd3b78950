//! The `--deform` / `--no-deform` pair shared by the commands that convert meshes.

/// Whether to deform active vertices (paper step 3). Off by default everywhere — in
/// `convert`, in benchmarks and in jobs — because it did not improve quality on the dev corpus
/// (docs/QUALITY.md).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct DeformArgs {
    /// Move active vertices towards the surface (paper step 3). Off by default: it did not
    /// improve quality on the dev corpus (docs/QUALITY.md).
    #[arg(long, conflicts_with = "no_deform")]
    pub deform: bool,
    /// Keep the grid undeformed (the default).
    #[arg(long)]
    pub no_deform: bool,
}

impl DeformArgs {
    /// Whether deformation is on.
    pub fn enabled(&self) -> bool {
        self.deform && !self.no_deform
    }
}
