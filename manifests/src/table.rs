//! Reading and writing manifests: CSV, JSONL or Parquet, chosen by extension. Any table with
//! a path column is a manifest (which column: [`crate::path_column`], one rule for the whole
//! manifest); `id` (or `sha256`) is optional. Relative paths are resolved against the
//! manifest's folder; URLs are kept as they are. Every other column is kept as provenance ([`RawRecord::extra`]).
//! Column names are read without case; two that are one name without it are refused
//! ([`crate::columns`]).

use crate::path_column::PathColumn;
pub use crate::raw::RawRecord;
use anyhow::Result;
use std::path::Path;

/// A manifest read: its rows and the column their paths came from.
#[derive(Debug, Clone)]
pub struct Manifest {
    /// The rows, in order.
    pub records: Vec<RawRecord>,
    /// The path column and why it was chosen.
    pub path_column: PathColumn,
}

/// Reads a manifest file whole; `path_column` is `--path-column` (otherwise
/// [`crate::path_column`]'s rule picks the column). Rows without a readable source are
/// refused, naming the first few. Jobs read theirs a batch at a time ([`crate::stream`]).
pub fn read(path: &Path, path_column: Option<&str>) -> Result<Manifest> {
    let mut stream = crate::stream::RowStream::open(path, path_column)?;
    let mut records = Vec::new();
    loop {
        let batch = stream.next_batch(1 << 16)?;
        if batch.is_empty() {
            break;
        }
        records.extend(batch.into_iter().map(|(_, r)| r));
    }
    stream.finish()?;
    let column = stream.path_column().clone();
    Ok(Manifest {
        records,
        path_column: column,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::ManifestRecord;
    use arrow_array::StringArray;

    fn extra(r: &RawRecord) -> Vec<(&str, &str)> {
        r.extra
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_str()))
            .collect()
    }

    #[test]
    fn every_other_column_is_kept_as_provenance() -> Result<()> {
        let dir = tempfile::tempdir()?;
        let csv = dir.path().join("m.csv");
        std::fs::write(&csv, "Path,ID,License,name\na.obj,x,cc0,A\nb.obj,y,,B\n")?;
        let m = read(&csv, None)?;
        assert_eq!(m.records[0].id.as_deref(), Some("x"));
        assert_eq!(extra(&m.records[0]), [("license", "cc0"), ("name", "A")]);
        assert_eq!(extra(&m.records[1]), [("license", ""), ("name", "B")]);
        // JSONL: every row gets every column; numbers are kept as their text.
        let jsonl = dir.path().join("m.jsonl");
        std::fs::write(
            &jsonl,
            "{\"uri\":\"a.obj\",\"likes\":3,\"sha256\":null}\n{\"uri\":\"b.obj\",\"tag\":\"t\"}\n",
        )?;
        let m = read(&jsonl, None)?;
        assert_eq!(extra(&m.records[0]), [("likes", "3"), ("tag", "")]);
        assert_eq!(extra(&m.records[1]), [("likes", ""), ("tag", "t")]);
        assert_eq!(m.records[1].column("tag"), Some("t"));
        assert_eq!(m.records[1].column("nope"), None);
        Ok(())
    }

    /// Issue 41, defect 4: `Licence,licence` kept the second column's values, and
    /// `id,uri,sha256,ID,Uri` took the ids and paths from `ID` and `Uri`. Each format refuses
    /// such names, naming both.
    #[test]
    fn columns_that_are_one_name_without_case_are_refused_naming_both() -> Result<()> {
        use arrow_array::{ArrayRef, RecordBatch};
        use std::sync::Arc;
        let dir = tempfile::tempdir()?;
        let refusal = |path: &Path| {
            read(path, None)
                .err()
                .map(|e| format!("{e:#}"))
                .unwrap_or_default()
        };
        let csv = dir.path().join("licence.csv");
        std::fs::write(
            &csv,
            "uri,Licence,licence
a.obj,cc0,by-nc
",
        )?;
        let e = refusal(&csv);
        assert!(e.contains("\"Licence\" and \"licence\""), "{e}");
        let csv = dir.path().join("ids.csv");
        std::fs::write(
            &csv,
            "id,uri,sha256,ID,Uri
mine,a.obj,,theirs,b.obj
",
        )?;
        let e = refusal(&csv);
        assert!(
            e.contains("\"id\" and \"ID\"") && e.contains("the header"),
            "{e}"
        );
        let jsonl = dir.path().join("m.jsonl");
        std::fs::write(
            &jsonl,
            "{\"uri\":\"a.obj\"}\n{\"uri\":\"b.obj\",\"Uri\":\"c.obj\"}\n",
        )?;
        let e = refusal(&jsonl);
        // (in the order serde_json keeps an object's keys)
        assert!(
            e.contains("line 2") && e.contains("\"Uri\"") && e.contains("\"uri\""),
            "{e}"
        );
        let parquet = dir.path().join("m.parquet");
        let column = |v: &str| Arc::new(StringArray::from(vec![v])) as ArrayRef;
        let batch = RecordBatch::try_from_iter([("uri", column("a.obj")), ("URI", column("b"))])?;
        let mut w = parquet::arrow::ArrowWriter::try_new(
            std::fs::File::create(&parquet)?,
            batch.schema(),
            None,
        )?;
        w.write(&batch)?;
        w.close()?;
        let e = refusal(&parquet);
        assert!(e.contains("\"uri\" and \"URI\""), "{e}");
        Ok(())
    }

    #[test]
    fn written_manifests_read_back_with_their_provenance() -> Result<()> {
        let dir = tempfile::tempdir()?;
        let record = |id: &str, licence: &str| ManifestRecord {
            id: id.into(),
            uri: dir
                .path()
                .join(format!("{id}.obj"))
                .to_string_lossy()
                .into_owned(),
            sha256: None,
            format: Some("obj".into()),
            extra: [("license".to_string(), licence.to_string())].into(),
        };
        let records = [record("a", "cc0"), record("b", "a, \"b\"")];
        for ext in ["csv", "jsonl", "parquet"] {
            let path = dir.path().join(format!("m.{ext}"));
            crate::write::write(&records, &path)?;
            let back = read(&path, None)?;
            let licences: Vec<&str> = back
                .records
                .iter()
                .filter_map(|r| r.column("license"))
                .collect();
            assert_eq!(licences, ["cc0", "a, \"b\""], "{ext}");
        }
        Ok(())
    }
}
