//! Presets: the job settings a consumer needs, as `sparc3d init --for CONSUMER` (and
//! `run DIR --job OUT --for CONSUMER`) sets them, so a job is made for a consumer in one flag.
//! The values come from the consumer's own module, the one place its frame is described
//! ([`trellis2::job_for_grid`], [`direct3d_s2::OBJECT_SPAN`]), which also names, in its
//! export's checks, the preset that fits a job that does not.
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

use crate::{direct3d_s2, trellis2, Consumer, Error, Result};
use serde_json::{json, Map, Value};

/// A consumer, and for the grid consumers the size of its grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Preset {
    /// The consumer the job is made for.
    pub consumer: Consumer,
    /// Its grid: TRELLIS.2's G (required), Direct3D-S2's resolution (optional).
    pub grid: Option<u32>,
}

/// The job settings a preset sets; every other key keeps its default.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Settings {
    /// `params.resolution`.
    pub resolution: Option<u32>,
    /// `params.object_span`.
    pub object_span: Option<f64>,
    /// `params.output_span`.
    pub output_span: Option<f64>,
    /// `samples.enabled = true` (the defaults serve every vector-set consumer).
    pub samples: bool,
    /// The consumer's condition views (`[renders]` recipe, views and size), used when the
    /// job renders (`--renders`, `[renders] enabled = true`); a job that does not keeps its
    /// config and fingerprint, since a disabled section is left out of both.
    pub renders: Option<RenderRecipe>,
}

/// A consumer's condition views: whose cameras and lights, how many, how large.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RenderRecipe {
    /// `[renders] recipe` (`trellis`, `trellis2`).
    pub recipe: &'static str,
    /// Views per item.
    pub views: u32,
    /// Side of a view in pixels.
    pub size: u32,
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
        let preset = Preset { consumer, grid };
        match (consumer, grid) {
            (Consumer::Cubvh, _) => Err(Error::Invalid(format!(
                "--for {text}: cubvh reads any job, it has no preset; presets: {}",
                Self::forms()
            ))),
            (Consumer::Trellis2, None) => Err(Error::Invalid(format!(
                "--for {text}: name TRELLIS.2's grid, e.g. trellis2@256, trellis2@512 or \
                 trellis2@1024 (the job converts at G + 6 and the export cuts the 3 free cells \
                 of each side off)"
            ))),
            (Consumer::Trellis2, Some(g)) if g > trellis2::MAX_GRID => {
                Err(Error::Invalid(format!(
                "--for {text}: TRELLIS.2's grid is at most {} here (the job converts at G + 6, \
                 and the largest resolution is {}); use trellis2@{} or a smaller grid",
                trellis2::MAX_GRID,
                sparcubes::params::MAX_RESOLUTION,
                trellis2::MAX_GRID
            )))
            }
            (Consumer::Trellis2 | Consumer::Direct3dS2, _) | (_, None) => Ok(preset),
            (_, Some(_)) => Err(Error::Invalid(format!(
                "--for {text}: {name} has no grid to name; use --for {name}"
            ))),
        }
    }

    /// Every form [`Preset::parse`] takes, for messages.
    pub fn forms() -> String {
        let mut forms: Vec<String> = Consumer::ALL
            .into_iter()
            .filter(|c| *c != Consumer::Cubvh)
            .map(|c| c.name().to_string())
            .collect();
        for f in &mut forms {
            if f == Consumer::Trellis2.name() {
                f.push_str("@G");
            } else if f == Consumer::Direct3dS2.name() {
                f.push_str("[@N]");
            }
        }
        forms.join(", ")
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
        match (self.consumer, self.grid) {
            (Consumer::Trellis2, Some(g)) => {
                let (resolution, span) = trellis2::job_for_grid(g);
                Settings {
                    resolution: Some(resolution),
                    output_span: Some(span),
                    renders: Some(trellis2::RENDERS),
                    ..Settings::default()
                }
            }
            (Consumer::Direct3dS2, grid) => Settings {
                resolution: grid,
                object_span: Some(direct3d_s2::OBJECT_SPAN),
                ..Settings::default()
            },
            (Consumer::Trellis2 | Consumer::Cubvh, _) => Settings::default(),
            (Consumer::Hunyuan3d21, _) => Settings {
                samples: true,
                renders: Some(crate::hunyuan3d::RENDERS),
                ..Settings::default()
            },
            (Consumer::Step1x3d, _) => Settings {
                samples: true,
                renders: Some(crate::step1x3d::RENDERS),
                ..Settings::default()
            },
            _ => Settings {
                samples: true,
                ..Settings::default()
            },
        }
    }
}

impl Settings {
    /// The settings as a partial job config (`{"params": {...}, "samples": {...}}`), under
    /// which a config file's keys are merged.
    pub fn overrides(&self) -> Value {
        let mut params = Map::new();
        if let Some(r) = self.resolution {
            params.insert("resolution".into(), json!(r));
        }
        if let Some(s) = self.object_span {
            params.insert("object_span".into(), json!(s));
        }
        if let Some(s) = self.output_span {
            params.insert("output_span".into(), json!(s));
        }
        let mut out = Map::new();
        if !params.is_empty() {
            out.insert("params".into(), Value::Object(params));
        }
        if self.samples {
            out.insert("samples".into(), json!({"enabled": true}));
        }
        if let Some(r) = self.renders {
            out.insert(
                "renders".into(),
                json!({"recipe": r.recipe, "views": r.views, "size": r.size}),
            );
        }
        Value::Object(out)
    }
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
    use crate::Frame;
    use sparcubes::Params;

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
        for c in [Consumer::Dora, Consumer::Step1x3d, Consumer::Triposg] {
            let s = Preset::parse(c.name()).map(|p| p.settings());
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
