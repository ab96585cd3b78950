//! Manifests end to end: what a job keeps of its manifest, and that a job without anything new
//! in its manifest converts to the same shards as before the `manifests` crate existed.

mod common;
use common::*;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use sparc3d_schema::digest;
use std::path::{Path, PathBuf};

/// The bundled example meshes copied into `dir/meshes`.
fn examples(dir: &Path) -> PathBuf {
    let root = dir.join("meshes");
    std::fs::create_dir_all(&root).unwrap_or_else(|e| panic!("{e}"));
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    for name in [
        "box_textured.glb",
        "cube.off",
        "cube_binary.ply",
        "sphere.obj",
        "wuson.stl",
    ] {
        std::fs::copy(examples.join(name), root.join(name))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    root
}

/// The shard files of a job in shard order.
fn shard_files(job: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(job.join("shards"))
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "parquet"));
    files.sort();
    files
}

/// The Arrow batches of one shard file.
fn batches(path: &Path) -> Vec<arrow_array::RecordBatch> {
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{e}"));
    ParquetRecordBatchReaderBuilder::try_new(f)
        .and_then(|b| b.build())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .map(|b| b.unwrap_or_else(|e| panic!("{e}")))
        .collect()
}

/// A job's content digest (as `inspect` computes it: shard digests combined) with every row's
/// `uri` cut to its file name, so that it does not depend on where the test runs.
fn path_free_digest(job: &Path) -> String {
    let digests: Vec<String> = shard_files(job)
        .iter()
        .map(|p| {
            let mut rows = Vec::new();
            for b in batches(p) {
                rows.extend(
                    sparc3d_schema::arrow::batch_to_rows(&b).unwrap_or_else(|e| panic!("{e}")),
                );
            }
            for r in &mut rows {
                r.uri = r.uri.rsplit('/').next().unwrap_or_default().to_string();
            }
            digest::rows_digest(&rows)
        })
        .collect();
    digest::combine(&digests)
}

/// The column names of a shard file.
fn column_names(path: &Path) -> Vec<String> {
    let f = std::fs::File::open(path).unwrap_or_else(|e| panic!("{e}"));
    let b = ParquetRecordBatchReaderBuilder::try_new(f).unwrap_or_else(|e| panic!("{e}"));
    b.schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect()
}

/// The content digest (uris cut to file names) of the five examples at 32³ in shards of two,
/// as sparc3d wrote them before the `manifests` crate and provenance columns existed.
const EXAMPLES_AT_32: &str = "2572a5ebd79276001379dd848109cb08499fdbf01a69b33f15f158c80a7d8741";

#[test]
fn a_job_without_extra_columns_converts_to_the_shards_of_before() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let meshes = examples(tmp.path());
    let job = tmp.path().join("job");
    let args = ["--resolution", "32", "--shard-size", "2", "--workers", "2"];
    ok(&[&["run", s(&meshes), "--job", s(&job)][..], &args].concat());
    assert_eq!(path_free_digest(&job), EXAMPLES_AT_32);
    let files = shard_files(&job);
    assert_eq!(files.len(), 3);
    let schema = sparc3d_schema::arrow::schema();
    let before: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    for f in &files {
        assert_eq!(column_names(f), before, "{}", f.display());
    }
}
