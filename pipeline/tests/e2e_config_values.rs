//! End to end, issue 47 items 1 and 2: every value of a job's config survives `job.json`
//! exactly (a config with random doubles in every float key initialises and runs: a value read
//! back 1 ulp off made every `run` refuse the job as edited), and `init --for CONSUMER` (also
//! `run DIR --job OUT --for …`) sets what the consumer needs, the flags beside it win, and
//! job.json names the preset.

mod common;

use common::*;
use serde_json::Value;
use sparc3d_schema::JobConfig;
use std::path::{Path, PathBuf};

/// A manifest of the bundled cube.
fn manifest(dir: &Path) -> PathBuf {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap_or_else(|e| panic!("{e}"));
    std::fs::copy(example("cube.off"), meshes.join("cube.off")).unwrap_or_else(|e| panic!("{e}"));
    let m = dir.join("m.csv");
    ok(&["manifest", "build", s(&meshes), "-o", s(&m)]);
    m
}

fn job_json(job: &Path) -> Value {
    let text = std::fs::read_to_string(job.join("job.json")).unwrap_or_else(|e| panic!("{e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"))
}

/// splitmix64: a fixed sequence of uniform doubles in [0, 1) with 53 random bits.
struct Doubles(u64);

impl Doubles {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Every float of `v` (a number that is not an integer) scaled by a random factor in
/// [0.9, 1): within every key's range, and a double with all its digits. Returns how many.
fn randomize_floats(v: &mut Value, rng: &mut Doubles) -> usize {
    match v {
        Value::Object(m) => m.values_mut().map(|x| randomize_floats(x, rng)).sum(),
        Value::Array(a) => a.iter_mut().map(|x| randomize_floats(x, rng)).sum(),
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(0.0) * (0.9 + 0.1 * rng.next());
            *v = serde_json::json!(x);
            1
        }
        _ => 0,
    }
}

/// A config with every section on (samples, refinement, object span), small counts and
/// random doubles in every float key; with how many floats it has.
fn random_config(seed: u64) -> (Value, usize) {
    let mut config = JobConfig::from_overrides(&serde_json::json!({
        "params": {"resolution": 32, "object_span": 0.75,
                   "refine": {"views": 2, "steps": 1, "image": 32}},
        "samples": {"enabled": true, "surface": 2000, "sharp": 500, "near": 3000,
                    "sharp_near": 800, "volume": 2000},
    }))
    .unwrap_or_else(|e| panic!("{e}"));
    config.params.deform = true; // its two keys decide the output
    let mut v = serde_json::to_value(&config).unwrap_or_else(|e| panic!("{e}"));
    let floats = randomize_floats(&mut v, &mut Doubles(seed));
    (v, floats)
}

#[test]
fn random_doubles_in_every_float_key_survive_init_and_run() {
    for seed in [1u64, 2, 3] {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let m = manifest(dir.path());
        let (wanted, floats) = random_config(seed);
        // shell, deform ×2, span, rate, timeout, sample rate, 3 + 8 σ, 2 bounds, angle.
        assert!(floats >= 18, "{floats} float keys");
        let toml_text = toml::to_string(&wanted).unwrap_or_else(|e| panic!("{e}"));
        let config_path = dir.path().join("job.toml");
        std::fs::write(&config_path, &toml_text).unwrap_or_else(|e| panic!("{e}"));
        let job = dir.path().join("job");
        ok(&[
            "init",
            s(&job),
            "--manifest",
            s(&m),
            "--config",
            s(&config_path),
        ]);
        // job.json holds the values read, and the fingerprint of the config read in-process.
        let file = job_json(&job);
        let expected: JobConfig =
            serde_json::from_value(wanted.clone()).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let stored: JobConfig = serde_json::from_value(file["config"].clone())
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert_eq!(stored, expected, "seed {seed}");
        let fingerprint = expected.fingerprint().unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(file["fingerprint"], fingerprint.as_str(), "seed {seed}");
        ok(&["run", s(&job), "--workers", "1"]);
        let st = status(&job);
        assert_eq!(st["ok"], 1, "seed {seed}: {st}");
    }
}

#[test]
fn trellis2_preset_sets_its_grid_exactly_and_the_export_takes_it_without_a_warning() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifest(dir.path());
    let job = dir.path().join("job");
    let init = sparc3d(&["init", s(&job), "--manifest", s(&m), "--for", "trellis2@48"]);
    let said = String::from_utf8_lossy(&init.stderr);
    assert!(init.status.success(), "{said}");
    assert!(
        said.contains("made for trellis2@48") && !said.contains("warning"),
        "{said}"
    );
    let config = &job_json(&job)["config"];
    assert_eq!(config["params"]["resolution"], 54);
    let (_, span) = sparc3d_formats::trellis2::job_for_grid(48);
    assert_eq!(config["params"]["output_span"].as_f64(), Some(span));
    assert!(config["params"].get("object_span").is_none());
    assert_eq!(config["preset"], "trellis2@48");
    ok(&["run", s(&job), "--workers", "1"]);
    let out = dir.path().join("t2");
    let export = sparc3d(&["export", s(&job), "--format", "trellis2", "--out", s(&out)]);
    let said = String::from_utf8_lossy(&export.stderr);
    assert!(
        export.status.success() && !said.contains("warning"),
        "{said}"
    );
    assert!(out.join("dual_grid_48").is_dir(), "{said}");
}

#[test]
fn flags_beside_a_preset_win_and_init_says_what_no_longer_fits() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifest(dir.path());
    // --resolution over trellis2@48's 54: the job is not in TRELLIS.2's frame, and init says
    // so with the export's own words.
    let job = dir.path().join("job");
    let init = sparc3d(&[
        "init",
        s(&job),
        "--manifest",
        s(&m),
        "--for",
        "trellis2@48",
        "--resolution",
        "64",
    ]);
    let said = String::from_utf8_lossy(&init.stderr);
    assert!(init.status.success(), "{said}");
    assert!(said.contains("warning: --for trellis2@48"), "{said}");
    assert_eq!(job_json(&job)["config"]["params"]["resolution"], 64);
    // A config file's key over the preset's: Dora's samples with the file's seed.
    let config_path = dir.path().join("seed.toml");
    std::fs::write(&config_path, "[samples]\nseed = 7\n").unwrap_or_else(|e| panic!("{e}"));
    let dora = dir.path().join("dora");
    ok(&[
        "init",
        s(&dora),
        "--manifest",
        s(&m),
        "--for",
        "dora",
        "--config",
        s(&config_path),
        "--resolution",
        "32",
    ]);
    let config = &job_json(&dora)["config"];
    assert_eq!(config["samples"]["enabled"], true);
    assert_eq!(config["samples"]["seed"], 7);
    // The same job made by hand has the same fingerprint: the preset is not fingerprinted,
    // and init again with the preset's values is the same job.
    let by_hand = dir.path().join("by_hand.toml");
    std::fs::write(&by_hand, "[samples]\nenabled = true\nseed = 7\n")
        .unwrap_or_else(|e| panic!("{e}"));
    let hand = dir.path().join("hand");
    let hand_args = [
        "init",
        s(&hand),
        "--manifest",
        s(&m),
        "--config",
        s(&by_hand),
        "--resolution",
        "32",
    ];
    ok(&hand_args);
    assert_eq!(
        job_json(&hand)["fingerprint"],
        job_json(&dora)["fingerprint"]
    );
    assert!(job_json(&hand)["config"].get("preset").is_none());
    let again = sparc3d(&[
        "init",
        s(&dora),
        "--manifest",
        s(&m),
        "--config",
        s(&by_hand),
        "--resolution",
        "32",
    ]);
    assert!(again.status.success(), "{:?}", again);
}

#[test]
fn run_with_job_takes_a_preset_and_refuses_it_for_a_job_made_otherwise() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = dir.path().join("meshes");
    manifest(dir.path());
    let job = dir.path().join("job");
    let run = sparc3d(&[
        "run",
        s(&meshes),
        "--job",
        s(&job),
        "--for",
        "direct3d-s2",
        "--resolution",
        "128",
        "--workers",
        "1",
    ]);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{said}");
    // Direct3D-S2's span; its VAEs read 512 or 1024, so 128 is warned of.
    assert!(said.contains("neither 512 nor 1024"), "{said}");
    let config = &job_json(&job)["config"];
    assert_eq!(config["params"]["object_span"], 0.95);
    assert_eq!(config["preset"], "direct3d-s2");
    // The same job again with another consumer's preset: its settings differ, refused.
    let other = sparc3d(&["run", s(&job), "--for", "dora"]);
    let said = String::from_utf8_lossy(&other.stderr);
    assert!(
        !other.status.success() && said.contains("samples"),
        "{said}"
    );
    let bad = sparc3d(&[
        "init",
        s(&dir.path().join("x")),
        "--manifest",
        s(&dir.path().join("m.csv")),
        "--for",
        "trellis2",
    ]);
    let said = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && said.contains("trellis2@512"),
        "{said}"
    );
}

/// Issue 64 item 10: a TRELLIS.2 grid past the largest is refused at the preset check with
/// its reason (before: `trellis2@4091`..`@4096` passed it and failed as "invalid job config:
/// invalid job config: …"); a config error is said once; a preset whose span a config file
/// changed is advised its own grid, not one from its resolution.
#[test]
fn presets_and_config_errors_are_refused_and_advised_plainly() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let m = manifest(dir.path());
    for grid in ["trellis2@4091", "trellis2@4096"] {
        let job = dir.path().join(grid);
        let init = sparc3d(&["init", s(&job), "--manifest", s(&m), "--for", grid]);
        let said = String::from_utf8_lossy(&init.stderr);
        assert!(!init.status.success(), "{said}");
        assert!(
            said.contains(&format!("--for {grid}")) && said.contains("at most 4090"),
            "{said}"
        );
        assert!(!said.contains("invalid job config"), "{said}");
    }
    let job = dir.path().join("big");
    let init = sparc3d(&["init", s(&job), "--manifest", s(&m), "--resolution", "5000"]);
    let said = String::from_utf8_lossy(&init.stderr);
    assert!(!init.status.success(), "{said}");
    assert_eq!(said.matches("invalid job config").count(), 1, "{said}");
    let span = dir.path().join("span.toml");
    std::fs::write(&span, "[params]\nobject_span = 0.8\n").unwrap_or_else(|e| panic!("{e}"));
    let job = dir.path().join("span");
    let init = sparc3d(&[
        "init",
        s(&job),
        "--manifest",
        s(&m),
        "--for",
        "trellis2@48",
        "--config",
        s(&span),
    ]);
    let said = String::from_utf8_lossy(&init.stderr);
    assert!(init.status.success(), "{said}");
    assert!(said.contains("grid of 48 exactly"), "{said}");
    assert!(!said.contains("trellis2@54"), "{said}");
}
