//! The `--inside-test` / `--no-inside-test` pair shared by the commands that convert meshes.

/// Whether to run the inside test (docs/ALGORITHM.md §2b). On by default everywhere — in
/// `convert`, `preview`, benchmarks and new jobs — since it made 10 dev meshes better and none
/// worse beyond noise at 256³ (docs/QUALITY.md, "Round four").
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InsideTestArgs {
    /// Run the inside test (the default; accepted so older command lines keep working):
    /// enclosed regions decided solid or air by the source's winding number, keeping parts
    /// inside hollow hulls and thin closed parts (docs/ALGORITHM.md §2b).
    #[arg(long, conflicts_with = "no_inside_test")]
    pub inside_test: bool,
    /// Switch the inside test off: every region the outside fill cannot reach stays solid
    /// (the behaviour before it became the default; the test costs 9–12 % of the conversion of
    /// the meshes it changes, docs/QUALITY.md).
    #[arg(long)]
    pub no_inside_test: bool,
}

impl InsideTestArgs {
    /// Whether the inside test is on.
    pub fn enabled(&self) -> bool {
        !self.no_inside_test
    }

    /// Whether either flag was given.
    pub fn given(&self) -> bool {
        self.inside_test || self.no_inside_test
    }
}
