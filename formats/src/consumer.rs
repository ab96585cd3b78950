//! What a consumer is to the rest of the house: the handle ([`Consumer`]) passed around,
//! whose methods read the consumer's [`Spec`] (its module's `SPEC`). [`Consumer::ALL`] is the
//! table of consumers, the one list of them; names, `--help` lines, frames, what the export
//! reads, the presets and their help texts all come from the specs, so a consumer is one
//! module with its `SPEC` plus one entry in that table, and states everything the export asks
//! of it (no field has a default).

pub use crate::spec::{PresetSpec, Reads, Spec, Views};
use crate::{ExportFile, Frame, Item, ItemExport, JobCheck, Listed, Result};
use sparcubes::samples::SampleParams;
use sparcubes::Params;
use std::path::Path;

/// A consumer, as the rest of the house passes it: a handle on its [`Spec`].
#[derive(Clone, Copy)]
pub struct Consumer(&'static Spec);

impl Consumer {
    /// Every consumer, in the order of `sparc3d export --help`: the table of consumers.
    pub const ALL: &'static [Consumer] = &[
        Consumer(&crate::hunyuan3d::SPEC),
        Consumer(&crate::dora::SPEC),
        Consumer(&crate::step1x3d::SPEC),
        Consumer(&crate::triposg::SPEC),
        Consumer(&crate::vecset::SPEC),
        Consumer(&crate::direct3d_s2::SPEC),
        Consumer(&crate::trellis2::SPEC),
        Consumer(&crate::cubvh::SPEC),
    ];

    /// Its description.
    pub fn spec(self) -> &'static Spec {
        self.0
    }

    /// The name `--format` takes.
    pub fn name(self) -> &'static str {
        self.0.name
    }

    /// One line for `--help`: what it writes.
    pub fn about(self) -> &'static str {
        self.0.about
    }

    /// The consumer named `name` ([`Consumer::name`]).
    pub fn from_name(name: &str) -> Option<Consumer> {
        Consumer::ALL.iter().copied().find(|c| c.name() == name)
    }

    /// The frames this consumer's files can be written in; the first is its default.
    pub fn frames(self) -> &'static [Frame] {
        self.0.frames
    }

    /// Whether this consumer's files are made from the stored samples (the grid layouts are
    /// made from the sparse cubes alone, so their export need not decode the sample columns).
    pub fn reads_samples(self) -> bool {
        self.0.reads.samples
    }

    /// Whether this consumer writes the stored appearance (the `[attributes]` columns) beside
    /// the shape: TRELLIS.2's PBR voxels; the export decodes those columns only for it.
    pub fn reads_attributes(self) -> bool {
        self.0.reads.attributes
    }

    /// The `[samples]` keys a job with `samples` (None: samples off) lacks for this consumer,
    /// each with what it needs (empty when nothing is missing).
    pub fn missing(self, samples: Option<&SampleParams>) -> Vec<String> {
        (self.0.missing)(samples)
    }

    /// What this consumer says of a job converted with `params`, written in `frame`, before
    /// anything is written: the settings it needs and the warnings to show.
    pub fn check(self, params: &Params, frame: Frame) -> JobCheck {
        (self.0.check)(params, frame)
    }

    /// The files of one item, paths relative to the export folder: the consumer's own, and
    /// for a consumer without a layout of condition views, the item's views in the plain
    /// multi-view layout ([`crate::renders::plain`]) when the job rendered them.
    pub fn files(self, item: &Item) -> Result<ItemExport> {
        let mut export = (self.0.files)(item)?;
        if let Views::Plain(placement) = self.0.views {
            export
                .files
                .extend(crate::renders::plain(item, &placement(item))?);
        }
        Ok(export)
    }

    /// The listing files of the items written (in item order), when this consumer reads one;
    /// `root` is where the export folder ends up (absolute), for listings of paths.
    pub fn listing(self, items: &[Listed], root: &Path) -> Result<Vec<ExportFile>> {
        (self.0.listing)(items, root)
    }
}

impl PartialEq for Consumer {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
    }
}

impl Eq for Consumer {}

impl std::fmt::Debug for Consumer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Consumer({})", self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_names_each_consumer_once_with_a_default_frame() {
        let mut names: Vec<&str> = Consumer::ALL.iter().map(|c| c.name()).collect();
        for c in Consumer::ALL {
            assert_eq!(Consumer::from_name(c.name()), Some(*c));
            assert!(!c.frames().is_empty(), "{c:?}");
            assert!(!c.about().is_empty() && !c.spec().title.is_empty(), "{c:?}");
        }
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Consumer::ALL.len());
    }

    #[test]
    fn a_consumer_made_from_the_cubes_alone_needs_no_samples() {
        for c in Consumer::ALL.iter().filter(|c| !c.reads_samples()) {
            assert!(c.missing(None).is_empty(), "{c:?}");
        }
        for c in Consumer::ALL.iter().filter(|c| c.reads_samples()) {
            assert!(!c.missing(None).is_empty(), "{c:?}");
        }
    }
}
