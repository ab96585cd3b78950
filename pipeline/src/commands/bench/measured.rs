//! What `bench` measures of each conversion, flattened into `bench` and `bench-one` alike so
//! that the parent forwards to its child exactly the flags the child declares.

/// The conversion's switches, the tensors' encoding and the optional condition views.
#[derive(Debug, clap::Args)]
pub struct MeasuredConversion {
    #[command(flatten)]
    pub conversion: crate::flags::conversion::ConversionArgs,
    /// zstd level of the encoded tensors.
    #[arg(long, default_value_t = 3)]
    pub zstd_level: i32,
    /// Also render each mesh's condition views with this recipe (`trellis`, `trellis2`;
    /// docs/RENDERS.md): the stage `renders` and the seconds a view.
    #[arg(long, value_parser = crate::commands::render::parse_recipe)]
    pub renders: Option<sparc3d_render::cond::Recipe>,
}

impl MeasuredConversion {
    /// These flags as `bench-one` takes them.
    pub fn as_flags(&self) -> Vec<String> {
        let mut flags: Vec<String> = self
            .conversion
            .as_flags()
            .into_iter()
            .map(String::from)
            .collect();
        flags.extend(["--zstd-level".to_string(), self.zstd_level.to_string()]);
        if let Some(recipe) = self.renders {
            flags.extend(["--renders".to_string(), recipe.name().to_string()]);
        }
        flags
    }
}
