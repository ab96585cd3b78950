//! Reading and writing manifests: CSV, JSONL or Parquet, chosen by extension. Any table with
//! a path column is a manifest (which column: [`crate::path_column`], one rule for the whole
//! manifest); `id` (or `sha256`) is optional. Relative paths are resolved against the
//! manifest's folder.

use crate::path_column::PathColumn;
use crate::record::ManifestRecord;
use anyhow::{bail, Context, Result};
use arrow_array::{Array, LargeStringArray, RecordBatch, StringArray, StringViewArray};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ArrowWriter;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A manifest row before its id is known: path, and optional id / sha256 / format.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawRecord {
    /// Optional id.
    pub id: Option<String>,
    /// Absolute path.
    pub uri: String,
    /// Optional sha256.
    pub sha256: Option<String>,
    /// Optional format.
    pub format: Option<String>,
}

impl From<ManifestRecord> for RawRecord {
    fn from(r: ManifestRecord) -> Self {
        Self {
            id: Some(r.id),
            uri: r.uri,
            sha256: r.sha256,
            format: r.format,
        }
    }
}

fn ext(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// A manifest read: its rows and the column their paths came from.
#[derive(Debug, Clone)]
pub struct Manifest {
    /// The rows, in order.
    pub records: Vec<RawRecord>,
    /// The path column and why it was chosen.
    pub path_column: PathColumn,
}

fn from_table(
    rows: Vec<BTreeMap<String, String>>,
    base: &Path,
    source: &Path,
    path_column: Option<&str>,
) -> Result<Manifest> {
    let column = crate::path_column::choose(&rows, path_column, source)?;
    crate::path_column::check_rows(&rows, &column, source)?;
    let mut out = Vec::with_capacity(rows.len());
    for row in rows {
        let get = |k: &str| row.get(k).filter(|v| !v.is_empty()).cloned();
        let uri = get(&column.name).unwrap_or_default();
        let p = PathBuf::from(&uri);
        let abs = if p.is_absolute() {
            uri
        } else {
            base.join(p).to_string_lossy().into_owned()
        };
        out.push(RawRecord {
            id: get("id"),
            uri: abs,
            sha256: get("sha256"),
            format: get("format"),
        });
    }
    Ok(Manifest {
        records: out,
        path_column: column,
    })
}

fn string_at(col: &dyn Array, i: usize) -> Option<String> {
    if col.is_null(i) {
        return None;
    }
    if let Some(a) = col.as_any().downcast_ref::<StringArray>() {
        return Some(a.value(i).to_string());
    }
    if let Some(a) = col.as_any().downcast_ref::<LargeStringArray>() {
        return Some(a.value(i).to_string());
    }
    if let Some(a) = col.as_any().downcast_ref::<StringViewArray>() {
        return Some(a.value(i).to_string());
    }
    None
}

fn read_parquet_table(path: &Path) -> Result<Vec<BTreeMap<String, String>>> {
    let f = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .with_context(|| format!("reading {}", path.display()))?
        .build()
        .with_context(|| format!("reading {}", path.display()))?;
    let mut rows = Vec::new();
    for batch in reader {
        let batch = batch.with_context(|| format!("reading {}", path.display()))?;
        let schema = batch.schema();
        for i in 0..batch.num_rows() {
            let mut m = BTreeMap::new();
            for (f, col) in schema.fields().iter().zip(batch.columns()) {
                if let Some(v) = string_at(col.as_ref(), i) {
                    m.insert(f.name().to_ascii_lowercase(), v);
                }
            }
            rows.push(m);
        }
    }
    Ok(rows)
}

/// Reads a manifest file; `path_column` is `--path-column` (otherwise [`crate::path_column`]'s rule
/// picks the column).
pub fn read(path: &Path, path_column: Option<&str>) -> Result<Manifest> {
    let base = path.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let base = std::fs::canonicalize(if base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        &base
    })
    .with_context(|| format!("resolving the folder of {}", path.display()))?;
    let rows: Vec<BTreeMap<String, String>> = match ext(path).as_str() {
        "csv" | "tsv" => {
            let mut r = csv::ReaderBuilder::new()
                .delimiter(if ext(path) == "tsv" { b'\t' } else { b',' })
                .from_path(path)
                .with_context(|| format!("opening {}", path.display()))?;
            let headers: Vec<String> = r
                .headers()
                .with_context(|| format!("reading {}", path.display()))?
                .iter()
                .map(|h| h.trim().to_ascii_lowercase())
                .collect();
            let mut rows = Vec::new();
            for rec in r.records() {
                let rec = rec.with_context(|| format!("reading {}", path.display()))?;
                rows.push(
                    headers
                        .iter()
                        .cloned()
                        .zip(rec.iter().map(|v| v.trim().to_string()))
                        .collect(),
                );
            }
            rows
        }
        "jsonl" | "ndjson" => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let mut rows = Vec::new();
            for (n, line) in text.lines().enumerate() {
                if line.trim().is_empty() {
                    continue;
                }
                let v: serde_json::Map<String, serde_json::Value> = serde_json::from_str(line)
                    .with_context(|| format!("{}: line {}", path.display(), n + 1))?;
                rows.push(
                    v.into_iter()
                        .filter_map(|(k, v)| match v {
                            serde_json::Value::String(s) => Some((k.to_ascii_lowercase(), s)),
                            serde_json::Value::Null => None,
                            other => Some((k.to_ascii_lowercase(), other.to_string())),
                        })
                        .collect(),
                );
            }
            rows
        }
        "parquet" => read_parquet_table(path)?,
        other => bail!(
            "{}: unknown manifest format {other:?} (expected .csv, .jsonl or .parquet)",
            path.display()
        ),
    };
    from_table(rows, &base, path, path_column)
}

/// Writes manifest records; the format follows the extension.
pub fn write(records: &[ManifestRecord], path: &Path) -> Result<()> {
    match ext(path).as_str() {
        "csv" => {
            let mut w = csv::Writer::from_path(path)
                .with_context(|| format!("creating {}", path.display()))?;
            w.write_record(["id", "uri", "sha256", "format"])?;
            for r in records {
                w.write_record([
                    r.id.as_str(),
                    r.uri.as_str(),
                    r.sha256.as_deref().unwrap_or(""),
                    r.format.as_deref().unwrap_or(""),
                ])?;
            }
            w.flush()
                .with_context(|| format!("writing {}", path.display()))?;
        }
        "jsonl" | "ndjson" => {
            let mut text = String::new();
            for r in records {
                text.push_str(&serde_json::to_string(r)?);
                text.push('\n');
            }
            std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        }
        "parquet" => {
            use arrow_schema::{DataType, Field, Schema};
            let schema = Arc::new(Schema::new(vec![
                Field::new("id", DataType::Utf8, false),
                Field::new("uri", DataType::Utf8, false),
                Field::new("sha256", DataType::Utf8, true),
                Field::new("format", DataType::Utf8, true),
            ]));
            let col = |f: &dyn Fn(&ManifestRecord) -> Option<&str>| -> Arc<dyn Array> {
                Arc::new(StringArray::from(records.iter().map(f).collect::<Vec<_>>()))
            };
            let batch = RecordBatch::try_new(
                schema.clone(),
                vec![
                    col(&|r| Some(r.id.as_str())),
                    col(&|r| Some(r.uri.as_str())),
                    col(&|r| r.sha256.as_deref()),
                    col(&|r| r.format.as_deref()),
                ],
            )?;
            let f = std::fs::File::create(path)
                .with_context(|| format!("creating {}", path.display()))?;
            let mut w = ArrowWriter::try_new(f, schema, None)?;
            w.write(&batch)?;
            w.close()
                .with_context(|| format!("writing {}", path.display()))?;
        }
        other => bail!(
            "{}: unknown manifest format {other:?} (expected .csv, .jsonl or .parquet)",
            path.display()
        ),
    }
    Ok(())
}
