//! `--path-column` and `--where`: how a manifest's rows are read for a job (`init`, `run
//! --job`, `add`).

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
