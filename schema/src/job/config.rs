//! The job config, its fingerprint, and the job file that freezes both into a job folder.

use crate::error::{Result, SchemaError};
use serde::{Deserialize, Serialize};
use serde_json::Value;

/// Per-item limits and retry policy. Run-time settings: they may change between runs of the
/// same job (`run --item-timeout`), so they are not part of the fingerprint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Seconds one item may run before it is killed and recorded as `timeout`.
    pub item_timeout_s: f64,
    /// Address-space limit of the process converting an item, in bytes (0: none).
    pub item_memory_bytes: u64,
    /// How many times a `crashed` item is retried before its failure is final.
    pub max_crash_retries: u32,
    /// How many times an item may be found started but unfinished after its worker was
    /// killed (kill -9, lost node) before it is recorded as `crashed`.
    pub max_interrupted_attempts: u32,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            item_timeout_s: 600.0,
            item_memory_bytes: 8 << 30,
            max_crash_retries: 2,
            max_interrupted_attempts: 5,
        }
    }
}

/// Everything that decides a job's output, plus its run-time [`Limits`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobConfig {
    /// Conversion parameters (resolution, margin, shell thickness, deformation).
    pub params: sparcubes::Params,
    /// Items per shard.
    pub shard_size: u32,
    /// zstd level of the tensor blobs.
    pub zstd_level: i32,
    /// Whether to extract the mesh of each item (gives `output_faces`).
    pub extract_mesh: bool,
    /// Whether to store the extracted mesh in the row (`mesh_vertices`, `mesh_faces`).
    pub store_mesh: bool,
    /// Fraction of ok items a later validation step samples.
    pub validation_sample_rate: f64,
    /// Per-item limits (not fingerprinted).
    pub limits: Limits,
    /// Vector-set samples drawn from each item's watertight mesh (`[samples]`). Left out of
    /// the canonical config while disabled, so jobs without samples keep their fingerprint.
    #[serde(default, skip_serializing_if = "SampleConfig::is_disabled")]
    pub samples: SampleConfig,
    /// The preset that chose some of these values (`init --for trellis2@512`, docs/FORMAT.md,
    /// "Presets"), as the job's record of what it was made for. Not fingerprinted and not
    /// compared (it names how the values were chosen; the values themselves are above), and
    /// left out while unset, so a job without it keeps its JSON and its fingerprint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Appearance sampled at each item's active cells (`[attributes]`). Left out of the
    /// canonical config while disabled, so jobs without it keep their fingerprint.
    #[serde(default, skip_serializing_if = "AttributeConfig::is_disabled")]
    pub attributes: AttributeConfig,
    /// Whether each ok row stores the quality columns (`quality = true`, the default; docs/
    /// FORMAT.md, "Quality columns"). A stored config without the key (every job made before
    /// the columns existed) reads as off and is written back without it, so such a job keeps
    /// its fingerprint and resumes writing the rows it wrote.
    #[serde(default, skip_serializing_if = "is_false")]
    pub quality: bool,
    /// Whether each ok row stores the output's shape signature (`shape_signature = true`, the
    /// default; docs/FORMAT.md, "Shape signature"), which `sparc3d dedup` groups by. Like
    /// [`JobConfig::quality`], a stored config without the key reads as off and is written
    /// back without it, so a job made before the column keeps its fingerprint and its rows.
    #[serde(default, skip_serializing_if = "is_false")]
    pub shape_signature: bool,
    /// Condition views rendered of each item's source (`[renders]`, docs/RENDERS.md). Left
    /// out of the canonical config while disabled, so jobs without it keep their fingerprint.
    #[serde(default, skip_serializing_if = "RenderConfig::is_disabled")]
    pub renders: RenderConfig,
}

/// Whether a flag is off (then left out of the canonical config).
fn is_false(b: &bool) -> bool {
    !*b
}

/// The `[attributes]` section of a job config: `enabled = true` stores base colour, metallic,
/// roughness and alpha for every active cell, read from the source's materials, textures and
/// vertex colours (docs/FORMAT.md, "Attributes").
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AttributeConfig {
    /// Whether each ok item gets the attribute columns.
    pub enabled: bool,
}

impl AttributeConfig {
    /// Whether attributes are off (the section is then left out of the canonical config).
    pub fn is_disabled(&self) -> bool {
        !self.enabled
    }
}

/// The `[renders]` section of a job config: `enabled = true` renders each ok item's source
/// with a consumer's cameras and lights (`recipe`, one of [`RenderConfig::RECIPES`]) and
/// stores the views in its row (docs/RENDERS.md, "In a job").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderConfig {
    /// Whether each ok item gets the render columns.
    pub enabled: bool,
    /// Whose cameras, view count, size and lights (`sparc3d_render::cond::Recipe::named`).
    pub recipe: String,
    /// Views per item (the recipe's count when unset).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub views: Option<u32>,
    /// Side of a view in pixels (the recipe's when unset).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size: Option<u32>,
    /// Mixed into each item's seed (the head of its source's sha256): another set of views.
    pub seed: u64,
}

impl Default for RenderConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            recipe: "trellis2".into(),
            views: None,
            size: None,
            seed: 0,
        }
    }
}

impl RenderConfig {
    /// The recipes a job may name (those of `sparc3d_render::cond::Recipe::ALL`; a test of
    /// the workers keeps the two lists equal).
    pub const RECIPES: [&'static str; 2] = ["trellis", "trellis2"];
    /// The view counts a job may ask for.
    pub const VIEWS: std::ops::RangeInclusive<u32> = 1..=256;
    /// The view sizes a job may ask for, in pixels.
    pub const SIZES: std::ops::RangeInclusive<u32> = 16..=4096;

    /// Whether renders are off (the section is then left out of the canonical config).
    pub fn is_disabled(&self) -> bool {
        !self.enabled
    }

    /// Refuses a recipe no renderer has and a view count or size out of range.
    fn validate(&self) -> std::result::Result<(), String> {
        if !Self::RECIPES.contains(&self.recipe.as_str()) {
            return Err(format!(
                "renders.recipe must be one of {}, got {:?}",
                Self::RECIPES.join(", "),
                self.recipe
            ));
        }
        let out = |key: &str, v: Option<u32>, r: &std::ops::RangeInclusive<u32>| match v {
            Some(v) if !r.contains(&v) => Err(format!(
                "renders.{key} must be in {}..={}, got {v}",
                r.start(),
                r.end()
            )),
            _ => Ok(()),
        };
        out("views", self.views, &Self::VIEWS)?;
        out("size", self.size, &Self::SIZES)
    }
}

/// The `[samples]` section of a job config: `enabled = true` alone draws the documented
/// defaults of [`sparcubes::samples::SampleParams`] (docs/FORMAT.md, "Samples").
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct SampleConfig {
    /// Whether each ok item gets sample columns.
    pub enabled: bool,
    /// Counts, noise scales, sharp-edge angle, dtype and seed.
    #[serde(flatten)]
    pub params: sparcubes::samples::SampleParams,
}

impl SampleConfig {
    /// Whether samples are off (the section is then left out of the canonical config).
    pub fn is_disabled(&self) -> bool {
        !self.enabled
    }
}

impl Default for JobConfig {
    fn default() -> Self {
        Self {
            params: sparcubes::Params::default(),
            shard_size: 256,
            zstd_level: 3,
            extract_mesh: true,
            store_mesh: false,
            validation_sample_rate: 0.01,
            limits: Limits::default(),
            samples: SampleConfig::default(),
            preset: None,
            attributes: AttributeConfig::default(),
            quality: true,
            shape_signature: true,
            renders: RenderConfig::default(),
        }
    }
}

/// Keys of the config that are excluded from the fingerprint.
pub const UNFINGERPRINTED: [&str; 2] = ["limits", "preset"];

/// Sorts object keys recursively so the JSON text is canonical.
fn canonical(v: &Value) -> Value {
    match v {
        Value::Object(m) => {
            let mut keys: Vec<&String> = m.keys().collect();
            keys.sort();
            let mut out = serde_json::Map::new();
            for k in keys {
                out.insert(k.clone(), canonical(&m[k]));
            }
            Value::Object(out)
        }
        Value::Array(a) => Value::Array(a.iter().map(canonical).collect()),
        other => other.clone(),
    }
}

fn to_value(config: &JobConfig) -> Result<Value> {
    serde_json::to_value(config).map_err(|source| SchemaError::Json {
        context: "serializing the job config".into(),
        source,
    })
}

/// Writes a canonical JSON text of sorted keys (serde_json keeps insertion order when its
/// `preserve_order` feature is on somewhere in the build, so sort explicitly).
fn canonical_text(v: &Value) -> String {
    match v {
        Value::Object(m) => {
            let mut keys: Vec<&String> = m.keys().collect();
            keys.sort();
            let parts: Vec<String> = keys
                .iter()
                .map(|k| format!("{}:{}", Value::String((*k).clone()), canonical_text(&m[*k])))
                .collect();
            format!("{{{}}}", parts.join(","))
        }
        Value::Array(a) => format!(
            "[{}]",
            a.iter().map(canonical_text).collect::<Vec<_>>().join(",")
        ),
        other => other.to_string(),
    }
}

impl JobConfig {
    /// The config as canonical JSON (sorted keys).
    pub fn to_canonical_json(&self) -> Result<String> {
        Ok(canonical_text(&canonical(&to_value(self)?)))
    }

    /// Fingerprint: hex sha256 of the schema version and the canonical JSON of the config
    /// without its run-time [`Limits`].
    pub fn fingerprint(&self) -> Result<String> {
        let mut v = to_value(self)?;
        if let Value::Object(m) = &mut v {
            for k in UNFINGERPRINTED {
                m.remove(k);
            }
        }
        let text = format!(
            "sparc3d-shard-v{}\n{}",
            crate::SCHEMA_VERSION,
            canonical_text(&v)
        );
        Ok(crate::hex::sha256_hex(text.as_bytes()))
    }

    /// Builds a config from defaults overlaid with a partial JSON object (e.g. a parsed
    /// `job.toml`). Unknown keys are refused with their dotted name.
    pub fn from_overrides(overrides: &Value) -> Result<Self> {
        let config = Self::overlaid(overrides)?;
        config.validate()?;
        Ok(config)
    }

    /// Defaults overlaid with a partial JSON object, not validated yet: typed overrides (the
    /// command line's) may still be set before [`JobConfig::validate`].
    pub fn overlaid(overrides: &Value) -> Result<Self> {
        let mut base = to_value(&Self::default())?;
        // The samples section is left out of a default config's JSON; offer its keys.
        if let Value::Object(m) = &mut base {
            let samples = serde_json::to_value(SampleConfig::default()).map_err(|source| {
                SchemaError::Json {
                    context: "serializing the samples config".into(),
                    source,
                }
            })?;
            m.insert("samples".into(), samples);
            m.insert("attributes".into(), serde_json::json!({ "enabled": false }));
            m.insert(
                "renders".into(),
                serde_json::json!({
                    "enabled": false, "recipe": "trellis2", "views": null, "size": null, "seed": 0
                }),
            );
            // `params.object_span` and `params.output_span` are left out while unset
            // (`Params::object_span`); offer them.
            if let Some(Value::Object(params)) = m.get_mut("params") {
                params.entry("object_span").or_insert(Value::Null);
                params.entry("output_span").or_insert(Value::Null);
                // `params.refine` too, as its default table when the override writes one,
                // so a misspelt setting is refused by its dotted name.
                params.entry("refine").or_insert(refine_base(overrides)?);
            }
        }
        merge(&mut base, overrides, "")?;
        let config: Self = serde_json::from_value(base).map_err(|source| SchemaError::Json {
            context: "job config".into(),
            source,
        })?;
        Ok(Self {
            params: config.params.settled(),
            samples: SampleConfig {
                params: config.samples.params.settled(),
                ..config.samples
            },
            ..config
        })
    }

    /// Refuses parameters the converter would refuse, a shard size of 0, a zstd level zstd
    /// does not have, a sample rate outside [0, 1] and an item time limit that is not a
    /// positive number of seconds; each message names the key and its valid range.
    pub fn validate(&self) -> Result<()> {
        self.params.validate().map_err(|e| SchemaError::Invalid {
            what: "job config",
            value: e.to_string(),
        })?;
        if self.samples.enabled {
            self.samples
                .params
                .validate()
                .map_err(|e| SchemaError::Invalid {
                    what: "job config",
                    value: e.to_string(),
                })?;
        }
        if self.shard_size == 0 {
            return Err(SchemaError::Invalid {
                what: "job config",
                value: "shard_size must be at least 1".into(),
            });
        }
        self.validate_settings()
    }

    /// The range checks of the keys beside `params`, `samples` and `shard_size`.
    fn validate_settings(&self) -> Result<()> {
        let invalid = |value: String| {
            Err(SchemaError::Invalid {
                what: "job config",
                value,
            })
        };
        let levels = zstd::compression_level_range();
        if !levels.contains(&self.zstd_level) {
            return invalid(format!(
                "zstd_level must be in {}..={}, got {}",
                levels.start(),
                levels.end(),
                self.zstd_level
            ));
        }
        if !(0.0..=1.0).contains(&self.validation_sample_rate) {
            return invalid(format!(
                "validation_sample_rate must be in [0, 1], got {}",
                self.validation_sample_rate
            ));
        }
        if self.renders.enabled {
            self.renders.validate().map(|_| ()).or_else(invalid)?;
        }
        let timeout = self.limits.item_timeout_s;
        if !(timeout.is_finite() && timeout > 0.0) {
            return invalid(format!(
                "limits.item_timeout_s must be a positive number of seconds, got {timeout}"
            ));
        }
        Ok(())
    }

    /// Dotted keys whose values differ between two configs (e.g. `params.resolution`); the
    /// [`JobConfig::preset`] is not compared (a job made by hand with a preset's values is
    /// the same job).
    pub fn diff_keys(&self, other: &JobConfig) -> Result<Vec<String>> {
        let mut out = Vec::new();
        diff(&to_value(self)?, &to_value(other)?, "", &mut out);
        out.retain(|k| k != "preset");
        out.sort();
        Ok(out)
    }
}

/// What `params.refine` is offered as before an override is merged: off (`null`), or the
/// default settings when the override writes a table of settings.
fn refine_base(overrides: &Value) -> Result<Value> {
    if !overrides
        .pointer("/params/refine")
        .is_some_and(Value::is_object)
    {
        return Ok(Value::Null);
    }
    let mut base =
        serde_json::to_value(sparcubes::refine::RefineParams::default()).map_err(|source| {
            SchemaError::Json {
                context: "serializing the refine settings".into(),
                source,
            }
        })?;
    // `image` is left out while automatic (`RefineParams::image`); offer it, so that
    // `[params.refine] image = 512` is a setting, not an unknown key.
    if let Value::Object(m) = &mut base {
        m.entry("image").or_insert(Value::Null);
    }
    Ok(base)
}

fn merge(base: &mut Value, over: &Value, path: &str) -> Result<()> {
    match (base, over) {
        (Value::Object(b), Value::Object(o)) => {
            for (k, v) in o {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match b.get_mut(k) {
                    Some(slot) => merge(slot, v, &p)?,
                    None => {
                        return Err(SchemaError::Invalid {
                            what: "config key",
                            value: p,
                        })
                    }
                }
            }
            Ok(())
        }
        (slot, v) => {
            *slot = v.clone();
            Ok(())
        }
    }
}

fn diff(a: &Value, b: &Value, path: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            for k in keys {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                match (x.get(k), y.get(k)) {
                    (Some(u), Some(v)) => diff(u, v, &p, out),
                    _ => out.push(p),
                }
            }
        }
        (u, v) if u != v => out.push(path.to_string()),
        _ => {}
    }
}

/// Lower-case hex of bytes ([`crate::hex::hex`], also found here by the crates that used it
/// before it had a module of its own).
pub use crate::hex::hex;

/// The job file (`job.json`): what `init` froze.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobFile {
    /// Schema version of the shards this job writes.
    pub schema_version: u32,
    /// Version of the tool that initialised the job.
    pub tool_version: String,
    /// The config.
    pub config: JobConfig,
    /// [`JobConfig::fingerprint`] of `config`.
    pub fingerprint: String,
    /// Items in the frozen manifest.
    pub items: u64,
    /// Number of shards.
    pub shards: u64,
    /// sha256 of the frozen manifest: of `manifest.jsonl` for a job whose frozen manifest is
    /// one file; of the index (its pages' sha256s, one a line: [`crate::job::manifest::index_sha256`])
    /// for a job kept in slices.
    pub manifest_sha256: String,
    /// The frozen manifest's index pages, in order, when it is kept in slices (one file per
    /// shard under `manifest/`, each page listing [`crate::job::manifest::PAGE_SHARDS`] shards'
    /// slices with their sha256s: docs/FORMAT.md, "The frozen manifest"). Absent for a job made
    /// before slices, whose frozen manifest is `manifest.jsonl` alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub manifest_pages: Option<Vec<crate::job::manifest::ManifestPage>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprint_ignores_limits_and_sees_params() -> Result<()> {
        let a = JobConfig::default();
        let mut b = a.clone();
        b.limits.item_timeout_s = 1.0;
        assert_eq!(a.fingerprint()?, b.fingerprint()?);
        b.params.resolution = 256;
        assert_ne!(a.fingerprint()?, b.fingerprint()?);
        assert_eq!(
            a.diff_keys(&b)?,
            vec!["limits.item_timeout_s", "params.resolution"]
        );
        assert_eq!(a.fingerprint()?.len(), 64);
        Ok(())
    }

    /// The canonical JSON of the default config as written before the inside test became
    /// the default (`Params::inside_test`): no `inside_test` key, since it was left out while
    /// off. Its fingerprint is pinned above: sha256 of `sparc3d-shard-v3`, a newline and this
    /// text without `limits`, with the f32 fields widened to f64 as the fingerprint writes them
    /// (0.45 as 0.44999998807907104), computed outside Rust.
    const OLD_DEFAULT_FINGERPRINT: &str =
        "a7712068316c66542d270a919f246ea5254f497543406fbe9a54bcce2e548281";

    const OLD_DEFAULT_CONFIG: &str = r#"{"extract_mesh":true,"limits":{"item_memory_bytes":8589934592,"item_timeout_s":600.0,"max_crash_retries":2,"max_interrupted_attempts":5},"params":{"deform":false,"deform_max":0.45,"deform_step":0.5,"margin_cells":3,"resolution":512,"shell_half_thickness":0.9},"shard_size":256,"store_mesh":false,"validation_sample_rate":0.01,"zstd_level":3}"#;

    /// [`OLD_DEFAULT_CONFIG`] read back.
    fn old_default_config() -> Result<JobConfig> {
        serde_json::from_str(OLD_DEFAULT_CONFIG).map_err(|source| SchemaError::Json {
            context: "test".into(),
            source,
        })
    }

    #[test]
    fn a_stored_config_without_the_key_keeps_the_inside_test_off_and_its_fingerprint() -> Result<()>
    {
        let old = old_default_config()?;
        assert!(!old.params.inside_test);
        assert_eq!(old.fingerprint()?, OLD_DEFAULT_FINGERPRINT);
        // Written back (a resumed job's job.json), it still has no key.
        assert!(!old.to_canonical_json()?.contains("inside_test"));
        Ok(())
    }

    #[test]
    fn attributes_are_off_by_default_and_change_the_fingerprint_only_when_on() -> Result<()> {
        let old = old_default_config()?;
        assert!(!old.attributes.enabled);
        assert_eq!(old.fingerprint()?, OLD_DEFAULT_FINGERPRINT);
        assert!(!JobConfig::default()
            .to_canonical_json()?
            .contains("attributes"));
        let on = JobConfig::from_overrides(&serde_json::json!({"attributes": {"enabled": true}}))?;
        assert!(on.attributes.enabled);
        assert_ne!(on.fingerprint()?, JobConfig::default().fingerprint()?);
        let off =
            JobConfig::from_overrides(&serde_json::json!({"attributes": {"enabled": false}}))?;
        assert_eq!(off.fingerprint()?, JobConfig::default().fingerprint()?);
        let typo = JobConfig::from_overrides(&serde_json::json!({"attributes": {"enable": true}}));
        assert!(typo.is_err_and(|e| e.to_string().contains("attributes.enable")));
        Ok(())
    }

    #[test]
    fn renders_are_off_by_default_and_change_the_fingerprint_only_when_on() -> Result<()> {
        let old = old_default_config()?;
        assert!(!old.renders.enabled);
        assert_eq!(old.fingerprint()?, OLD_DEFAULT_FINGERPRINT);
        let default = JobConfig::default();
        assert!(!default.to_canonical_json()?.contains("renders"));
        let on = JobConfig::from_overrides(&serde_json::json!({"renders": {"enabled": true}}))?;
        assert_eq!(on.renders.recipe, "trellis2");
        assert_ne!(on.fingerprint()?, default.fingerprint()?);
        let more = serde_json::json!({"renders": {"enabled": true, "views": 24}});
        assert_ne!(
            JobConfig::from_overrides(&more)?.fingerprint()?,
            on.fingerprint()?
        );
        let off = serde_json::json!({"renders": {"enabled": false, "recipe": "trellis"}});
        assert_eq!(
            JobConfig::from_overrides(&off)?.fingerprint()?,
            default.fingerprint()?
        );
        let refused = |v: serde_json::Value, says: &str| {
            let e = JobConfig::from_overrides(&v)
                .map(|_| ())
                .unwrap_err()
                .to_string();
            assert!(e.contains(says), "{e}");
        };
        refused(
            serde_json::json!({"renders": {"enabled": true, "recipe": "blender"}}),
            "renders.recipe",
        );
        refused(
            serde_json::json!({"renders": {"enabled": true, "views": 0}}),
            "renders.views",
        );
        refused(
            serde_json::json!({"renders": {"enabled": true, "size": 8}}),
            "renders.size",
        );
        refused(
            serde_json::json!({"renders": {"enable": true}}),
            "renders.enable",
        );
        Ok(())
    }

    #[test]
    fn a_new_config_has_the_inside_test_on_and_its_own_fingerprint() -> Result<()> {
        let new = JobConfig::default();
        assert!(new.params.inside_test);
        assert!(new.to_canonical_json()?.contains("\"inside_test\":true"));
        assert_ne!(new.fingerprint()?, OLD_DEFAULT_FINGERPRINT);
        // `inside_test = false` under `[params]` (and `quality = false`, `shape_signature =
        // false`, the columns that came later) gives back the old default, fingerprint too.
        let off = JobConfig::from_overrides(&serde_json::json!({
            "params": {"inside_test": false}, "quality": false, "shape_signature": false}))?;
        assert!(!off.params.inside_test);
        assert_eq!(off.fingerprint()?, OLD_DEFAULT_FINGERPRINT);
        assert!(!off.to_canonical_json()?.contains("inside_test"));
        // (The sealing asks the inside test, so switching the test off switches it off too.)
        assert_eq!(
            off.diff_keys(&new)?,
            vec![
                "params.inside_test",
                "params.seal_openings",
                "quality",
                "shape_signature"
            ]
        );
        Ok(())
    }

    /// The canonical JSON of the default config as written after the inside test became the
    /// default and before the sealing of openings existed (`Params::seal_openings`): no
    /// `seal_openings` key. Its fingerprint is the one `sparc3d init` of that release wrote
    /// into job.json for a default job.
    const INSIDE_TEST_ERA_CONFIG: &str = r#"{"extract_mesh":true,"limits":{"item_memory_bytes":8589934592,"item_timeout_s":600.0,"max_crash_retries":2,"max_interrupted_attempts":5},"params":{"deform":false,"deform_max":0.45,"deform_step":0.5,"inside_test":true,"margin_cells":3,"resolution":512,"shell_half_thickness":0.9},"shard_size":256,"store_mesh":false,"validation_sample_rate":0.01,"zstd_level":3}"#;
    const INSIDE_TEST_ERA_FINGERPRINT: &str =
        "a4e8c0d24cb21d80dfdd56bbb52be3c6dfc0af8ed224c37516fd159ac585b654";

    #[test]
    fn a_stored_config_without_the_key_keeps_the_sealing_off_and_its_fingerprint() -> Result<()> {
        let old: JobConfig =
            serde_json::from_str(INSIDE_TEST_ERA_CONFIG).map_err(|source| SchemaError::Json {
                context: "test".into(),
                source,
            })?;
        assert!(old.params.inside_test && !old.params.seal_openings);
        assert_eq!(old.fingerprint()?, INSIDE_TEST_ERA_FINGERPRINT);
        assert!(!old.to_canonical_json()?.contains("seal_openings"));
        // The new default seals, with a fingerprint of its own; `seal_openings = false` gives
        // back the old one.
        let new = JobConfig::default();
        assert!(new.to_canonical_json()?.contains("\"seal_openings\":true"));
        assert_ne!(new.fingerprint()?, INSIDE_TEST_ERA_FINGERPRINT);
        let off = JobConfig::from_overrides(&serde_json::json!({
            "params": {"seal_openings": false}, "quality": false, "shape_signature": false}))?;
        assert_eq!(off.fingerprint()?, INSIDE_TEST_ERA_FINGERPRINT);
        assert_eq!(
            off.diff_keys(&new)?,
            vec!["params.seal_openings", "quality", "shape_signature"]
        );
        Ok(())
    }

    /// The canonical JSON of a samples job as `init` wrote it before the sharp-near samples
    /// existed (`SampleParams::sharp_near`): `[samples] enabled = true` gave 124928 surface,
    /// 249856 near points at σ 0.005 and 0.05, and no `sharp_near` keys. Its fingerprint was
    /// computed outside Rust as `OLD_DEFAULT_FINGERPRINT`'s (sha256 of `sparc3d-shard-v3`, a
    /// newline and the sorted text without `limits`, the f32 fields widened).
    const SHARP_NEAR_ERA_SAMPLES_CONFIG: &str = r#"{"extract_mesh":true,"limits":{"item_memory_bytes":8589934592,"item_timeout_s":600.0,"max_crash_retries":2,"max_interrupted_attempts":5},"params":{"deform":false,"deform_max":0.45,"deform_step":0.5,"inside_test":true,"margin_cells":3,"resolution":512,"seal_openings":true,"shell_half_thickness":0.9},"samples":{"dtype":"f16","enabled":true,"near":249856,"near_bound":0.25,"near_sigmas":[0.005,0.05],"seed":0,"sharp":124928,"sharp_angle_deg":15.0,"surface":124928,"volume":249856,"volume_bound":1.05},"shard_size":256,"store_mesh":false,"validation_sample_rate":0.01,"zstd_level":3}"#;
    const SHARP_NEAR_ERA_SAMPLES_FINGERPRINT: &str =
        "31439e9d48c33892e8d79a745ee3781dca9b630063467e681ad210fb2d25996b";

    #[test]
    fn a_stored_samples_config_keeps_its_counts_draws_no_sharp_near_and_keeps_its_fingerprint(
    ) -> Result<()> {
        let old: JobConfig =
            serde_json::from_str(SHARP_NEAR_ERA_SAMPLES_CONFIG).map_err(|source| {
                SchemaError::Json {
                    context: "test".into(),
                    source,
                }
            })?;
        let p = &old.samples.params;
        assert!(old.samples.enabled);
        assert_eq!((p.surface, p.near, p.volume), (124_928, 249_856, 249_856));
        assert_eq!(p.near_sigmas, vec![0.005, 0.05]);
        assert_eq!((p.sharp_near, p.sharp_near_sigmas.len()), (0, 0));
        old.validate()?;
        assert_eq!(old.fingerprint()?, SHARP_NEAR_ERA_SAMPLES_FINGERPRINT);
        // Written back (a resumed job's job.json), it has no sharp-near key and reads back
        // as the same config.
        let text = old.to_canonical_json()?;
        assert!(!text.contains("sharp_near"));
        let back: JobConfig = serde_json::from_str(&text).map_err(|source| SchemaError::Json {
            context: "test".into(),
            source,
        })?;
        assert_eq!(back, old);
        // `enabled = true` alone now has the new defaults and a fingerprint of its own.
        let new = JobConfig::from_overrides(&serde_json::json!({"samples": {"enabled": true}}))?;
        let d = sparcubes::samples::SampleParams::default();
        assert_eq!(new.samples.params, d);
        assert_eq!(
            (d.surface, d.near, d.sharp_near),
            (204_800, 600_000, 262_144)
        );
        assert_eq!(d.near_sigmas, vec![0.001, 0.005, 0.05]);
        assert_eq!(d.sharp_near_sigmas.len(), 8);
        assert!(new.to_canonical_json()?.contains("\"sharp_near\":262144"));
        assert_ne!(new.fingerprint()?, SHARP_NEAR_ERA_SAMPLES_FINGERPRINT);
        // The old counts given explicitly, with `sharp_near = 0`, are the old job again.
        let again = JobConfig::from_overrides(&serde_json::json!({"samples": {
            "enabled": true, "surface": 124_928, "near": 249_856, "near_sigmas": [0.005, 0.05],
            "sharp_near": 0}, "quality": false, "shape_signature": false}))?;
        assert_eq!(again.fingerprint()?, SHARP_NEAR_ERA_SAMPLES_FINGERPRINT);
        assert_eq!(
            again.diff_keys(&new)?,
            vec![
                "quality",
                "samples.near",
                "samples.near_sigmas",
                "samples.sharp_near",
                "samples.sharp_near_sigmas",
                "samples.surface",
                "shape_signature"
            ]
        );
        Ok(())
    }

    #[test]
    fn quality_columns_are_on_for_new_jobs_and_off_for_stored_configs_without_the_key() -> Result<()>
    {
        // Every job stored before the columns existed: off, and written back without the key.
        for (text, fingerprint) in [
            (OLD_DEFAULT_CONFIG, OLD_DEFAULT_FINGERPRINT),
            (INSIDE_TEST_ERA_CONFIG, INSIDE_TEST_ERA_FINGERPRINT),
        ] {
            let old: JobConfig =
                serde_json::from_str(text).map_err(|source| SchemaError::Json {
                    context: "test".into(),
                    source,
                })?;
            assert!(!old.quality);
            assert_eq!(old.fingerprint()?, fingerprint);
            assert!(!old.to_canonical_json()?.contains("quality"));
        }
        let new = JobConfig::default();
        assert!(new.quality && new.to_canonical_json()?.contains("\"quality\":true"));
        let off = JobConfig::from_overrides(&serde_json::json!({"quality": false}))?;
        assert_eq!(off.diff_keys(&new)?, vec!["quality"]);
        assert_ne!(off.fingerprint()?, new.fingerprint()?);
        Ok(())
    }

    /// The canonical JSON of the default config as `sparc3d init` wrote it after the quality
    /// columns came and before the shape signature (`JobConfig::shape_signature`), with the
    /// fingerprint it wrote into job.json.
    const QUALITY_ERA_CONFIG: &str = r#"{"extract_mesh":true,"limits":{"item_memory_bytes":8589934592,"item_timeout_s":600.0,"max_crash_retries":2,"max_interrupted_attempts":5},"params":{"deform":false,"deform_max":0.45,"deform_step":0.5,"inside_test":true,"margin_cells":3,"resolution":512,"seal_openings":true,"shell_half_thickness":0.9},"quality":true,"shard_size":256,"store_mesh":false,"validation_sample_rate":0.01,"zstd_level":3}"#;
    const QUALITY_ERA_FINGERPRINT: &str =
        "10e9f98243b7c861604d847baf0f78d71c1d03fa55b789b8f2f2ce5081e72c5d";

    #[test]
    fn the_shape_signature_is_on_for_new_jobs_and_off_for_stored_configs_without_the_key(
    ) -> Result<()> {
        // Every job stored before the column existed: off, its fingerprint, and written back
        // without the key.
        for (text, fingerprint) in [
            (OLD_DEFAULT_CONFIG, OLD_DEFAULT_FINGERPRINT),
            (INSIDE_TEST_ERA_CONFIG, INSIDE_TEST_ERA_FINGERPRINT),
            (QUALITY_ERA_CONFIG, QUALITY_ERA_FINGERPRINT),
        ] {
            let old: JobConfig =
                serde_json::from_str(text).map_err(|source| SchemaError::Json {
                    context: "test".into(),
                    source,
                })?;
            assert!(!old.shape_signature);
            assert_eq!(old.fingerprint()?, fingerprint);
            assert!(!old.to_canonical_json()?.contains("shape_signature"));
        }
        let new = JobConfig::default();
        assert!(new.shape_signature);
        assert!(new
            .to_canonical_json()?
            .contains("\"shape_signature\":true"));
        assert_ne!(new.fingerprint()?, QUALITY_ERA_FINGERPRINT);
        // `shape_signature = false` gives back the quality era's default, fingerprint too.
        let off = JobConfig::from_overrides(&serde_json::json!({"shape_signature": false}))?;
        assert_eq!(off.fingerprint()?, QUALITY_ERA_FINGERPRINT);
        assert_eq!(off.diff_keys(&new)?, vec!["shape_signature"]);
        Ok(())
    }

    #[test]
    fn an_object_span_is_stored_only_when_set_and_refused_when_it_leaves_no_margin() -> Result<()> {
        // Unset (every job stored before the key existed), the canonical JSON has no key, so
        // the pinned fingerprints above hold.
        let new = JobConfig::default();
        assert!(!new.to_canonical_json()?.contains("object_span"));
        let d3 = JobConfig::from_overrides(&serde_json::json!({"params": {"object_span": 0.95}}))?;
        assert_eq!(d3.params.object_span, Some(0.95));
        assert!(d3.to_canonical_json()?.contains("\"object_span\":0.95"));
        assert_eq!(d3.diff_keys(&new)?, vec!["params.object_span"]);
        // 0.95 at resolution 64 leaves 1.6 cells per side: refused, naming the key.
        let e = JobConfig::from_overrides(
            &serde_json::json!({"params": {"object_span": 0.95, "resolution": 64}}),
        );
        assert!(
            matches!(e, Err(ref err) if err.to_string().contains("object_span")),
            "{e:?}"
        );
        Ok(())
    }

    #[test]
    fn the_refinement_is_stored_only_when_on_with_its_settings_and_checked_by_name() -> Result<()> {
        // Off (every job stored before the key existed): no key, the pinned fingerprints hold.
        let new = JobConfig::default();
        assert!(!new.to_canonical_json()?.contains("refine"));
        let off = JobConfig::from_overrides(&serde_json::json!({"params": {"refine": false}}))?;
        assert_eq!(off.fingerprint()?, new.fingerprint()?);
        // `refine = true`: the default settings, written whole but for the picture size, which
        // follows the resolution unless set (a job stored with `image` keeps it).
        let on = JobConfig::from_overrides(&serde_json::json!({"params": {"refine": true}}))?;
        assert_eq!(
            on.params.refine,
            Some(sparcubes::refine::RefineParams::default())
        );
        let written = on.to_canonical_json()?;
        assert!(written.contains("\"refine\":{\"rate\":"), "{written}");
        assert!(!written.contains("image"), "{written}");
        assert_eq!(on.diff_keys(&new)?, vec!["params.refine"]);
        // A table: its settings over the defaults; read back from the canonical JSON.
        let table = JobConfig::from_overrides(
            &serde_json::json!({"params": {"refine": {"views": 8, "steps": 5}}}),
        )?;
        let r = table.params.refine.map(|r| (r.views, r.steps, r.image));
        assert_eq!(r, Some((8, 5, None)));
        let back: JobConfig =
            serde_json::from_str(&table.to_canonical_json()?).map_err(|source| {
                SchemaError::Json {
                    context: "test".into(),
                    source,
                }
            })?;
        assert_eq!(back, table);
        // The picture size is a setting too, though the default table leaves it out.
        let sized =
            JobConfig::from_overrides(&serde_json::json!({"params": {"refine": {"image": 512}}}))?;
        assert_eq!(sized.params.refine.and_then(|r| r.image), Some(512));
        // Out of range or misspelt: refused by name.
        for (bad, key) in [
            (serde_json::json!({"views": 0}), "refine.views"),
            (serde_json::json!({"image": 4096}), "refine.image"),
            (serde_json::json!({"veiws": 8}), "params.refine.veiws"),
        ] {
            let e = JobConfig::from_overrides(&serde_json::json!({"params": {"refine": bad}}));
            assert!(
                matches!(&e, Err(err) if err.to_string().contains(key)),
                "{key}: {e:?}"
            );
        }
        Ok(())
    }

    #[test]
    fn overrides_merge_and_unknown_keys_are_refused() -> Result<()> {
        let c = JobConfig::from_overrides(
            &serde_json::json!({"shard_size": 8, "params": {"resolution": 128}}),
        )?;
        assert_eq!(c.shard_size, 8);
        assert_eq!(c.params.resolution, 128);
        assert_eq!(
            c.params.margin_cells,
            JobConfig::default().params.margin_cells
        );
        let e = JobConfig::from_overrides(&serde_json::json!({"params": {"resolutoin": 1}}));
        assert!(
            matches!(e, Err(SchemaError::Invalid { value, .. }) if value == "params.resolutoin")
        );
        assert!(
            JobConfig::from_overrides(&serde_json::json!({"params": {"resolution": 2}})).is_err()
        );
        Ok(())
    }

    #[test]
    fn samples_section_defaults_validates_and_stays_out_when_off() -> Result<()> {
        let off = JobConfig::default();
        assert!(!off.to_canonical_json()?.contains("samples"));
        let on = JobConfig::from_overrides(&serde_json::json!({"samples": {"enabled": true}}))?;
        assert!(on.samples.enabled);
        assert_eq!(
            on.samples.params,
            sparcubes::samples::SampleParams::default()
        );
        assert_ne!(on.fingerprint()?, off.fingerprint()?);
        assert!(on.to_canonical_json()?.contains("\"near_sigmas\""));
        let e = JobConfig::from_overrides(
            &serde_json::json!({"samples": {"enabled": true, "volume": 1u64 << 40}}),
        );
        assert!(
            matches!(e, Err(SchemaError::Invalid { value, .. }) if value.contains("samples.volume"))
        );
        let e = JobConfig::from_overrides(&serde_json::json!({"samples": {"enabeld": true}}));
        assert!(matches!(e, Err(SchemaError::Invalid { value, .. }) if value == "samples.enabeld"));
        let f32s = JobConfig::from_overrides(
            &serde_json::json!({"samples": {"enabled": true, "dtype": "f32", "surface": 10}}),
        )?;
        assert_eq!(
            f32s.samples.params.dtype,
            sparcubes::samples::Precision::F32
        );
        assert_eq!(f32s.samples.params.surface, 10);
        // A config written before samples existed still reads.
        let mut v =
            serde_json::to_value(JobConfig::default()).map_err(|source| SchemaError::Json {
                context: "test".into(),
                source,
            })?;
        if let Value::Object(m) = &mut v {
            m.remove("samples");
        }
        let back: JobConfig = serde_json::from_value(v).map_err(|source| SchemaError::Json {
            context: "test".into(),
            source,
        })?;
        assert_eq!(back, JobConfig::default());
        Ok(())
    }

    /// Doubles with all 17 significant digits, each in `[lo, hi)`, from a fixed seed
    /// (splitmix64): values a parser that is not correctly rounded reads 1 ulp off.
    fn doubles(seed: u64, lo: f64, hi: f64) -> impl Iterator<Item = f64> {
        let mut state = seed;
        std::iter::repeat_with(move || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            lo + (hi - lo) * ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        })
    }

    #[test]
    fn every_float_of_a_config_reads_back_from_its_job_file_exactly() -> Result<()> {
        // issue 47: `object_span = 0.9402889552238807` initialised, then every `run` found the
        // config edited, since job.json read it back 1 ulp off.
        let json = |e| SchemaError::Json {
            context: "test".into(),
            source: e,
        };
        let mut spans = doubles(47, 0.5, 0.9);
        let mut rates = doubles(48, 0.0, 1.0);
        let mut sigmas = doubles(49, 1e-4, 0.1);
        for _ in 0..200 {
            let mut config =
                JobConfig::from_overrides(&serde_json::json!({"samples": {"enabled": true}}))?;
            config.params.object_span = spans.next();
            config.validation_sample_rate = rates.next().unwrap_or(0.5);
            config.limits.item_timeout_s = 600.0 * rates.next().unwrap_or(0.5) + 1.0;
            config.samples.params.near_sigmas = sigmas.by_ref().take(3).collect();
            config.samples.params.near_bound = 0.25 + sigmas.next().unwrap_or(0.0);
            config.validate()?;
            let file = JobFile {
                schema_version: crate::SCHEMA_VERSION,
                tool_version: "test".into(),
                fingerprint: config.fingerprint()?,
                config,
                items: 1,
                shards: 1,
                manifest_sha256: String::new(),
                manifest_pages: None,
            };
            let text = serde_json::to_vec_pretty(&file).map_err(json)?;
            let back: JobFile = serde_json::from_slice(&text).map_err(json)?;
            assert_eq!(back.config, file.config);
            assert_eq!(back.config.fingerprint()?, file.fingerprint);
        }
        Ok(())
    }

    #[test]
    fn the_preset_is_kept_but_neither_fingerprinted_nor_compared() -> Result<()> {
        let plain = JobConfig::from_overrides(&serde_json::json!({"samples": {"enabled": true}}))?;
        let made_for = JobConfig {
            preset: Some("dora".into()),
            ..plain.clone()
        };
        assert_eq!(made_for.fingerprint()?, plain.fingerprint()?);
        assert!(made_for.diff_keys(&plain)?.is_empty());
        assert!(made_for
            .to_canonical_json()?
            .contains("\"preset\":\"dora\""));
        assert!(!plain.to_canonical_json()?.contains("preset"));
        Ok(())
    }

    #[test]
    fn canonical_json_sorts_keys() -> Result<()> {
        let text = JobConfig::default().to_canonical_json()?;
        let ext = text.find("\"extract_mesh\"").unwrap_or(usize::MAX);
        let lim = text.find("\"limits\"").unwrap_or(0);
        assert!(ext < lim);
        Ok(())
    }
}
