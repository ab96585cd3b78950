//! Presets: the job settings a consumer needs, as `sparc3d init --for CONSUMER` (and
//! `run DIR --job OUT --for CONSUMER`) sets them, so a job is made for a consumer in one flag.
//! Each consumer states its own in its `SPEC` ([`crate::spec::Spec::preset`], `None` for
//! one that has none), the one place its frame is described
//! ([`crate::trellis2::job_for_grid`], [`crate::direct3d_s2::OBJECT_SPAN`]), which also names,
//! in its export's checks, the preset that fits a job that does not; here they are parsed,
//! listed and merged into a config.
//!
//! - `trellis2@G`: TRELLIS.2's dual grid of G exactly: `resolution = G + 6` and
//!   `output_span = 0.99999·G/(G + 6)`, the output's box framed as TRELLIS.2's `read_mesh`
//!   places it (docs/FORMAT.md, "TRELLIS.2's dual grid dataset");
//! - `direct3d-s2` (or `direct3d-s2@N`, also `resolution = N`): `object_span = 0.95`, its
//!   objects' span; the export warns off resolutions other than 512 and 1024;
//! - `hunyuan3d-2.1`, `dora`, `step1x-3d`, `triposg`, `vecset-npz`: `[samples] enabled = true`,
//!   whose defaults serve all of them.
//!
//! cubvh reads any job and has none.

use crate::spec::PresetSpec;
pub use crate::spec::{GridPreset, RenderRecipe, Settings};
use crate::{Consumer, Error, Result};
use sparcubes::Params;

/// A consumer, and for the grid consumers the size of its grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Preset {
    /// The consumer the job is made for.
    pub consumer: Consumer,
    /// Its grid: TRELLIS.2's G (required), Direct3D-S2's resolution (optional).
    pub grid: Option<u32>,
}

impl Preset {
    /// The preset `text` names: a consumer's `--format` name, with `@G` for TRELLIS.2's grid
    /// (required) and Direct3D-S2's resolution (optional). Errors name the valid forms.
    pub fn parse(text: &str) -> Result<Preset> {
        let (name, grid) = match text.split_once('@') {
            Some((name, g)) => (name, Some(parse_grid(text, g)?)),
            None => (text, None),
        };
        let Some(consumer) = Consumer::from_name(name) else {
            return Err(Error::Invalid(format!(
                "--for {text}: no such consumer; presets: {}",
                Self::forms()
            )));
        };
        let Some(spec) = consumer.spec().preset else {
            return Err(Error::Invalid(format!(
                "--for {text}: {name} reads any job, it has no preset; presets: {}",
                Self::forms()
            )));
        };
        match (spec.grid, grid) {
            (Some(g), grid) => (g.accept)(text, grid)?,
            (None, Some(_)) => {
                return Err(Error::Invalid(format!(
                    "--for {text}: {name} has no grid to name; use --for {name}"
                )))
            }
            (None, None) => {}
        }
        Ok(Preset { consumer, grid })
    }

    /// Every form [`Preset::parse`] takes, for messages.
    pub fn forms() -> String {
        let forms: Vec<String> = with_presets()
            .map(|(c, spec)| format!("{}{}", c.name(), spec.grid.map_or("", |g| g.form)))
            .collect();
        forms.join(", ")
    }

    /// `--for`'s list of presets, each form with what it does, those that need a grid first:
    /// "`trellis2@G` (TRELLIS.2's grid of G exactly), ..., `vecset-npz` (samples on)".
    pub fn help() -> String {
        let mut out = String::new();
        let presets = in_help_order();
        for (i, (c, spec)) in presets.iter().enumerate() {
            let form = spec.grid.map_or("", |g| g.form);
            if i > 0 {
                out.push_str(", ");
            }
            out.push_str(&format!("`{}{form}`", c.name()));
            let next = presets.get(i + 1).map(|(_, s)| s.help);
            if next != Some(spec.help) {
                out.push_str(&format!(" ({})", spec.help));
            }
        }
        out
    }

    /// The presets' condition views, for `--renders`' help, in the order of [`Preset::help`]:
    /// "TRELLIS.2's 16 views of 1024², Hunyuan3D-2.1's 24 of 512², ...".
    pub fn renders_help() -> String {
        let views: Vec<String> = in_help_order()
            .into_iter()
            .filter_map(|(c, spec)| Some((c.spec().title, spec.renders?)))
            .enumerate()
            .map(|(i, (title, r))| {
                let views = if i == 0 { " views" } else { "" };
                format!("{title}'s {}{views} of {}²", r.views, r.size)
            })
            .collect();
        views.join(", ")
    }

    /// The text [`Preset::parse`] reads back (what a job's config stores as `preset`).
    pub fn name(&self) -> String {
        match self.grid {
            Some(g) => format!("{}@{g}", self.consumer.name()),
            None => self.consumer.name().to_string(),
        }
    }

    /// What the preset sets.
    pub fn settings(&self) -> Settings {
        let Some(spec) = self.consumer.spec().preset else {
            return Settings::default();
        };
        let params = spec.grid.map(|g| (g.params)(self.grid)).unwrap_or_default();
        Settings {
            samples: spec.samples,
            renders: spec.renders,
            ..params
        }
    }

    /// What a job made with this preset lacks, in the preset's own terms, when a config key
    /// or flag changed what it set ([`GridPreset::misfit`]); `None` to let the consumer's
    /// check speak.
    pub fn misfit(&self, params: &Params) -> Option<String> {
        let grid = self.consumer.spec().preset?.grid?;
        (grid.misfit)(self.grid?, params)
    }
}

/// The consumers with a preset, in table order.
fn with_presets() -> impl Iterator<Item = (Consumer, PresetSpec)> {
    Consumer::ALL
        .iter()
        .filter_map(|c| Some((*c, c.spec().preset?)))
}

/// The consumers with a preset, those whose preset needs a grid first, then those with an
/// optional grid, then the rest, each group in table order.
fn in_help_order() -> Vec<(Consumer, PresetSpec)> {
    let mut presets: Vec<_> = with_presets().collect();
    presets.sort_by_key(|(_, spec)| match spec.grid {
        Some(g) if g.required => 0,
        Some(_) => 1,
        None => 2,
    });
    presets
}

/// The grid of `@G` in `text`: a whole number of at least 8.
fn parse_grid(text: &str, g: &str) -> Result<u32> {
    match g.parse::<u32>() {
        Ok(n) if (8..=sparcubes::params::MAX_RESOLUTION).contains(&n) => Ok(n),
        _ => Err(Error::Invalid(format!(
            "--for {text}: {g:?} is not a grid size (a whole number, 8 to {})",
            sparcubes::params::MAX_RESOLUTION
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{trellis2, Frame};

    /// The params a preset's settings give over the defaults.
    fn params_of(s: Settings) -> Params {
        let mut p = Params::default();
        if let Some(r) = s.resolution {
            p.resolution = r;
        }
        p.object_span = s.object_span;
        p.output_span = s.output_span;
        p
    }

    #[test]
    fn each_preset_gives_a_job_its_consumer_takes_without_a_warning() {
        for text in [
            "trellis2@128",
            "trellis2@512",
            "direct3d-s2",
            "direct3d-s2@1024",
        ] {
            let preset = Preset::parse(text).unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!(preset.name(), text);
            let params = params_of(preset.settings());
            assert!(params.validate().is_ok(), "{text}");
            let check = preset.consumer.check(&params, Frame::Consumer);
            assert_eq!(check, crate::JobCheck::default(), "{text}");
        }
        let t = Preset::parse("trellis2@128").map(|p| p.settings());
        assert_eq!(t.ok().and_then(|s| s.resolution), Some(134));
        for name in ["dora", "step1x-3d", "triposg"] {
            let c = Consumer::from_name(name).unwrap_or_else(|| panic!("{name}"));
            let s = Preset::parse(name).map(|p| p.settings());
            assert!(
                s.is_ok_and(|s| s.samples && s.object_span.is_none()),
                "{c:?}"
            );
            // The defaults that `samples.enabled = true` draws serve it.
            let d = sparcubes::samples::SampleParams::default();
            assert!(c.missing(Some(&d)).is_empty(), "{c:?}");
        }
    }

    #[test]
    fn every_consumer_of_samples_has_a_preset_that_draws_them() {
        for c in Consumer::ALL {
            let preset = c.spec().preset;
            let draws = preset.is_some_and(|p| p.samples);
            assert_eq!(draws, c.reads_samples(), "{c:?}");
            let grid = preset.and_then(|p| p.grid);
            if let Some(g) = grid {
                // A required grid is refused when missing, an optional one taken.
                assert_eq!((g.accept)(c.name(), None).is_err(), g.required, "{c:?}");
            }
        }
    }

    #[test]
    fn the_help_texts_list_every_preset_from_the_table() {
        assert_eq!(
            Preset::help(),
            "`trellis2@G` (TRELLIS.2's grid of G exactly), `direct3d-s2[@N]` (its span; N its \
             resolution), `hunyuan3d-2.1`, `dora`, `step1x-3d`, `triposg`, `vecset-npz` \
             (samples on)"
        );
        assert_eq!(
            Preset::renders_help(),
            "TRELLIS.2's 16 views of 1024², Hunyuan3D-2.1's 24 of 512², Step1X-3D's 20 of 512²"
        );
        assert_eq!(
            Preset::forms(),
            "hunyuan3d-2.1, dora, step1x-3d, triposg, vecset-npz, direct3d-s2[@N], trellis2@G"
        );
    }

    #[test]
    fn malformed_presets_are_refused_with_the_forms_that_exist() {
        for (text, says) in [
            ("trellis2", "trellis2@512"),
            ("trellis2@abc", "not a grid size"),
            ("trellis2@4", "not a grid size"),
            // Converted at G + 6: past 4090 no job could be made (issue 64 item 10).
            ("trellis2@4091", "at most 4090"),
            ("trellis2@4096", "at most 4090"),
            ("dora@512", "no grid"),
            ("cubvh", "any job"),
            ("nerf", "trellis2@G"),
        ] {
            let e = Preset::parse(text).map(|p| p.name());
            assert!(
                matches!(&e, Err(err) if err.to_string().contains(says)),
                "{text}: {e:?}"
            );
        }
    }

    #[test]
    fn a_grid_preset_overrides_its_grid_alone() {
        let s = Preset::parse("trellis2@64").map(|p| p.settings().overrides());
        let v = s.unwrap_or_default();
        assert_eq!(v["params"]["resolution"], 70);
        assert!(v.get("samples").is_none());
    }

    #[test]
    fn the_largest_trellis2_grid_makes_a_job_of_the_largest_resolution() {
        let p = Preset::parse("trellis2@4090").map(|p| p.settings().resolution);
        assert!(
            matches!(p, Ok(Some(sparcubes::params::MAX_RESOLUTION))),
            "{p:?}"
        );
    }

    #[test]
    fn a_trellis2_preset_with_another_span_is_advised_its_own_grid() {
        let (resolution, _) = trellis2::job_for_grid(48);
        let mut p = Params::with_resolution(resolution);
        p.object_span = Some(0.8);
        let line = trellis2::preset_misfit(48, &p).unwrap_or_default();
        assert!(
            line.contains("grid of 48") && !line.contains("54"),
            "{line}"
        );
        // The preset's own span, or another resolution: nothing to say here.
        p.object_span = None;
        p.output_span = Some(trellis2::output_span_for(48));
        assert_eq!(trellis2::preset_misfit(48, &p), None);
        let other = Params::with_resolution(64);
        assert_eq!(trellis2::preset_misfit(48, &other), None);
    }
}
