//! Writing manifests (`manifest build`): CSV, JSONL or Parquet, chosen by extension, with the
//! columns `id`, `uri`, `sha256`, `format` and then the provenance columns in name order (only
//! when some record has any, so a folder's manifest is written as before they existed).

use crate::raw::ext;
use crate::record::ManifestRecord;
use anyhow::{bail, Context, Result};
use arrow_array::{Array, RecordBatch, StringArray};
use parquet::arrow::ArrowWriter;
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

/// The provenance column names of `records`, in name order.
fn extra_names(records: &[ManifestRecord]) -> Vec<String> {
    let names: BTreeSet<&String> = records.iter().flat_map(|r| r.extra.keys()).collect();
    names.into_iter().cloned().collect()
}

/// One record's value in each column, in the order `id`, `uri`, `sha256`, `format`, then
/// `extra` (`None`: no value).
fn cells<'a>(r: &'a ManifestRecord, extra: &[String]) -> Vec<Option<&'a str>> {
    let mut out = vec![
        Some(r.id.as_str()),
        Some(r.uri.as_str()),
        r.sha256.as_deref(),
        r.format.as_deref(),
    ];
    out.extend(
        extra
            .iter()
            .map(|n| r.extra.get(n).map(String::as_str).filter(|v| !v.is_empty())),
    );
    out
}

/// Writes manifest records; the format follows the extension. The file is written under a
/// temporary name beside `path` and renamed into place, so a failed write leaves no half
/// manifest (and an earlier one stays as it was).
pub fn write(records: &[ManifestRecord], path: &Path) -> Result<()> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        name.as_deref().unwrap_or("manifest"),
        std::process::id()
    ));
    let written = write_to(records, path, &tmp);
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
        return written;
    }
    std::fs::rename(&tmp, path).with_context(|| {
        let _ = std::fs::remove_file(&tmp);
        format!("moving {} into place", path.display())
    })
}

/// Writes `records` into `tmp` in the format `path`'s extension names.
fn write_to(records: &[ManifestRecord], path: &Path, tmp: &Path) -> Result<()> {
    let extra = extra_names(records);
    let mut header = vec![
        "id".to_string(),
        "uri".into(),
        "sha256".into(),
        "format".into(),
    ];
    header.extend(extra.iter().cloned());
    match ext(path).as_str() {
        "csv" => write_csv(records, &header, &extra, tmp),
        "jsonl" | "ndjson" => write_jsonl(records, &header, &extra, tmp),
        "parquet" => write_parquet(records, &header, &extra, tmp),
        other => bail!(
            "{}: unknown manifest format {other:?} (expected .csv, .jsonl or .parquet)",
            path.display()
        ),
    }
}

fn write_csv(
    records: &[ManifestRecord],
    header: &[String],
    extra: &[String],
    path: &Path,
) -> Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    w.write_record(header)?;
    for r in records {
        w.write_record(cells(r, extra).into_iter().map(|c| c.unwrap_or("")))?;
    }
    w.flush()
        .with_context(|| format!("writing {}", path.display()))
}

/// One object per line; a column without a value is left out of its line.
fn write_jsonl(
    records: &[ManifestRecord],
    header: &[String],
    extra: &[String],
    path: &Path,
) -> Result<()> {
    let mut text = String::new();
    for r in records {
        let mut line = String::from("{");
        for (name, value) in header.iter().zip(cells(r, extra)) {
            let Some(value) = value else { continue };
            if line.len() > 1 {
                line.push(',');
            }
            line.push_str(&serde_json::to_string(name)?);
            line.push(':');
            line.push_str(&serde_json::to_string(value)?);
        }
        line.push('}');
        text.push_str(&line);
        text.push('\n');
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

fn write_parquet(
    records: &[ManifestRecord],
    header: &[String],
    extra: &[String],
    path: &Path,
) -> Result<()> {
    use arrow_schema::{DataType, Field, Schema};
    let rows: Vec<Vec<Option<&str>>> = records.iter().map(|r| cells(r, extra)).collect();
    let fields = header
        .iter()
        .enumerate()
        .map(|(i, n)| Field::new(n, DataType::Utf8, i >= 2))
        .collect::<Vec<_>>();
    let schema = Arc::new(Schema::new(fields));
    let columns: Vec<Arc<dyn Array>> = (0..header.len())
        .map(|i| {
            let values: Vec<Option<&str>> = rows.iter().map(|r| r[i]).collect();
            Arc::new(StringArray::from(values)) as Arc<dyn Array>
        })
        .collect();
    let batch = RecordBatch::try_new(schema.clone(), columns)?;
    let f = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = ArrowWriter::try_new(f, schema, None)?;
    w.write(&batch)?;
    w.close()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
