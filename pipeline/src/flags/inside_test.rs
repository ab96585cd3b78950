//! The flags of the winding-number rules shared by the commands that convert meshes: the
//! inside test (`--inside-test` / `--no-inside-test`) and the sealing of small openings
//! (`--no-seal-openings`), which asks the inside test's winding number.

/// Whether to run the inside test (docs/ALGORITHM.md §6) and seal small openings (§4). Both
/// on by default everywhere — in `convert`, `preview`, benchmarks and new jobs: the inside
/// test made 10 dev meshes better and none worse beyond noise at 256³
/// (docs/record/QUALITY-history.md, "Round four"), the sealing keeps nearly closed solids solid
/// (docs/QUALITY.md, issue 26).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InsideTestArgs {
    /// Run the inside test (the default; accepted so older command lines keep working):
    /// enclosed regions decided solid or air by the source's winding number, keeping parts
    /// inside hollow hulls and thin closed parts (docs/ALGORITHM.md §6).
    #[arg(long, conflicts_with = "no_inside_test")]
    pub inside_test: bool,
    /// Switch the inside test off: every region the outside fill cannot reach stays solid
    /// (the behaviour before it became the default; the test costs 9–12 % of the conversion of
    /// the meshes it changes, docs/QUALITY.md). Also switches off the sealing of openings,
    /// which asks the test's winding number.
    #[arg(long)]
    pub no_inside_test: bool,
    /// Do not seal small openings: a closed part with a hole wider than about a voxel becomes
    /// a thin shell as a whole, as before the sealing existed (docs/ALGORITHM.md §4).
    #[arg(long)]
    pub no_seal_openings: bool,
}

impl InsideTestArgs {
    /// Whether the inside test is on.
    pub fn enabled(&self) -> bool {
        !self.no_inside_test
    }

    /// Whether small openings are sealed (never without the inside test).
    pub fn seal_enabled(&self) -> bool {
        self.enabled() && !self.no_seal_openings
    }

    /// Whether any of the flags was given.
    pub fn given(&self) -> bool {
        self.inside_test || self.no_inside_test || self.no_seal_openings
    }

    /// Sets both rules in `params`.
    pub fn apply_to(&self, params: &mut sparcubes::Params) {
        params.inside_test = self.enabled();
        params.seal_openings = self.seal_enabled();
    }

    /// The flags that ask a child `sparc3d` process for the same rules.
    pub fn as_flags(&self) -> Vec<&'static str> {
        let mut flags = Vec::new();
        if !self.enabled() {
            flags.push("--no-inside-test");
        } else if !self.seal_enabled() {
            flags.push("--no-seal-openings");
        }
        flags
    }
}
