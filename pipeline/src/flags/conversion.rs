//! The conversion's switches that `convert`, `bench` and `bench-one` share as one group:
//! deformation ([`deform`](super::deform)) and the inside test's rules
//! ([`inside_test`](super::inside_test)), with the parameters they set and the flags that ask a
//! child `sparc3d` process for the same.

use super::deform::DeformArgs;
use super::inside_test::InsideTestArgs;

/// `--deform` / `--no-deform` and the inside test's flags.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ConversionArgs {
    /// Whether to deform active vertices.
    #[command(flatten)]
    pub deform: DeformArgs,
    /// The inside test and the sealing of small openings.
    #[command(flatten)]
    pub inside_test: InsideTestArgs,
}

impl ConversionArgs {
    /// The library's parameters at grid resolution `resolution` with these switches.
    pub fn params(&self, resolution: u32) -> sparcubes::Params {
        let mut params = sparcubes::Params::with_resolution(resolution);
        params.deform = self.deform.enabled();
        self.inside_test.apply_to(&mut params);
        params
    }

    /// The flags that ask a child `sparc3d` process for the same switches.
    pub fn as_flags(&self) -> Vec<&'static str> {
        let mut flags = self.inside_test.as_flags();
        if self.deform.enabled() {
            flags.push("--deform");
        }
        flags
    }
}
