//! Reading a manifest a batch of rows at a time, in bounded memory whatever its size (CSV,
//! TSV, JSONL, Parquet): each row becomes a [`RawRecord`] with its path resolved, or the reason
//! it has no readable source. The path column follows [`crate::path_column`]'s rule. A CSV
//! manifest names its columns in its header, so one pass reads it; with several path-like
//! columns (and no `--path-column`) a first pass over the file finds which hold local paths.
//! A JSONL or Parquet manifest's columns are those some row has a value in, and every item
//! carries every column, so a first pass finds them all.

use crate::path_column::{self, PathColumn, ValueSurvey, LISTED_ROWS};
use crate::problems::Problems;
use crate::raw::{ext, number_at, string_at, RawRecord};
use crate::record::{KNOWN_COLUMNS, PATH_COLUMNS};
use anyhow::{bail, Context, Result};
use arrow_array::RecordBatch;
use parquet::arrow::arrow_reader::{ParquetRecordBatchReader, ParquetRecordBatchReaderBuilder};
use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// One row read: its number in the manifest (1-based) and its record.
pub type Row = (u64, RawRecord);

/// A manifest opened for reading a batch of rows at a time.
pub struct RowStream {
    path: PathBuf,
    base: PathBuf,
    rows: Rows,
    column: PathColumn,
    /// Whether the column still has to show a value in some row (chosen from the header).
    unproven: bool,
    extra_names: Vec<String>,
    read: u64,
    /// The rows without a readable source, refused by [`RowStream::finish`].
    bad: Problems,
}

impl RowStream {
    /// Opens the manifest at `path`; `given` is `--path-column`.
    pub fn open(path: &Path, given: Option<&str>) -> Result<Self> {
        let base = base_folder(path)?;
        let (rows, header) = Rows::open(path)?;
        let candidates = header.as_ref().map(|h| path_candidates(h));
        let needs_survey = match (&candidates, given) {
            (None, _) => true,
            (Some(_), Some(_)) => false,
            (Some(c), None) => c.len() >= 2,
        };
        let (names, column, unproven) = if needs_survey {
            let (found, survey, rows) = survey(path)?;
            if rows == 0 {
                return Err(no_rows(path));
            }
            let names = header.map_or(found, |h| h.into_iter().collect());
            (
                names,
                path_column::choose_from(&survey, given, path)?,
                false,
            )
        } else {
            let column = match (given, candidates.as_deref()) {
                (Some(name), _) => path_column::given_column(name.trim().to_ascii_lowercase()),
                (None, Some([only])) => path_column::only_column(only),
                _ => return Err(path_column::no_path_column(path)),
            };
            (
                header.unwrap_or_default().into_iter().collect(),
                column,
                true,
            )
        };
        let extra_names = names
            .into_iter()
            .filter(|n| *n != column.name && !KNOWN_COLUMNS.contains(&n.as_str()))
            .collect();
        Ok(Self {
            path: path.to_path_buf(),
            base,
            rows,
            column,
            unproven,
            extra_names,
            read: 0,
            bad: Problems::default(),
        })
    }

    /// The path column and why it was chosen.
    pub fn path_column(&self) -> &PathColumn {
        &self.column
    }

    /// The provenance columns every record carries, in name order.
    pub fn extra_names(&self) -> &[String] {
        &self.extra_names
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.read
    }

    /// The next rows with a readable source, out of at most `max` read; none at the end of the
    /// manifest. The others are gathered for [`RowStream::finish`] to refuse.
    pub fn next_batch(&mut self, max: usize) -> Result<Vec<Row>> {
        let mut out = Vec::with_capacity(max.min(1 << 16));
        // Rows are read until some have a source or the manifest ends: an empty batch is the
        // end, never a stretch of bad rows.
        while out.is_empty() {
            let mut seen = 0;
            while seen < max.max(1) {
                let Some(row) = self.rows.next_row(&self.path)? else {
                    return Ok(out);
                };
                seen += 1;
                self.read += 1;
                if self.unproven && row.get(&self.column.name).is_some_and(|v| !v.is_empty()) {
                    self.unproven = false;
                }
                let n = self.read;
                match self.record(row) {
                    Ok(record) => out.push((n, record)),
                    Err(why) => self.bad.add(|| format!("row {n}: {why}"), LISTED_ROWS),
                }
            }
        }
        Ok(out)
    }

    /// What the whole manifest, read to its end, says against itself: no rows at all, a path
    /// column chosen from the header that no row has a value in, or rows without a readable
    /// source in it (the first few named).
    pub fn finish(&self) -> Result<()> {
        if self.read == 0 {
            return Err(no_rows(&self.path));
        }
        if self.unproven {
            return Err(match self.column.why.starts_with("given") {
                true => path_column::no_value_in(&self.column.name, &self.path),
                false => path_column::no_path_column(&self.path),
            });
        }
        if self.bad.count() > 0 {
            let (column, total) = (&self.column, self.read);
            return Err(path_column::rows_refusal(
                &self.path, column, &self.bad, total,
            ));
        }
        Ok(())
    }

    /// `row` as a record, or why it has no readable source.
    fn record(&self, row: BTreeMap<String, String>) -> std::result::Result<RawRecord, String> {
        if let Some(why) = path_column::row_problem(&row, &self.column) {
            return Err(why);
        }
        let get = |k: &str| row.get(k).filter(|v| !v.is_empty()).cloned();
        let uri = get(&self.column.name).unwrap_or_default();
        let p = Path::new(&uri);
        let uri = if p.is_absolute() || path_column::is_url(&uri) {
            uri
        } else {
            self.base.join(p).to_string_lossy().into_owned()
        };
        Ok(RawRecord {
            id: get("id"),
            uri,
            sha256: get("sha256"),
            format: get("format"),
            extra: self
                .extra_names
                .iter()
                .map(|n| (n.clone(), row.get(n).cloned().unwrap_or_default()))
                .collect(),
        })
    }
}

/// The folder relative paths of the manifest at `path` are resolved against.
fn base_folder(path: &Path) -> Result<PathBuf> {
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let base = if base.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        base
    };
    std::fs::canonicalize(&base)
        .with_context(|| format!("resolving the folder of {}", path.display()))
}

/// The path-like columns among a header's names, in order of preference.
fn path_candidates(header: &[String]) -> Vec<&'static str> {
    PATH_COLUMNS
        .into_iter()
        .filter(|c| header.iter().any(|h| h == c))
        .collect()
}

/// A first pass over the manifest at `path`: every column some row has a value for, which
/// hold values and local paths, and how many rows there are.
fn survey(path: &Path) -> Result<(BTreeSet<String>, ValueSurvey, u64)> {
    let (mut rows, _) = Rows::open(path)?;
    let mut names = BTreeSet::new();
    let mut values = ValueSurvey::default();
    let mut count = 0u64;
    while let Some(row) = rows.next_row(path)? {
        count += 1;
        for name in row.keys() {
            if !names.contains(name) {
                names.insert(name.clone());
            }
        }
        values.add(&row);
    }
    Ok((names, values, count))
}

/// The refusal of a manifest without a single row.
fn no_rows(path: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: the manifest has no rows (a manifest lists one mesh a row, with its path in a \
         column named one of {})",
        path.display(),
        PATH_COLUMNS.join(", ")
    )
}

/// A manifest's rows as maps from folded column names to values, one at a time.
enum Rows {
    Csv {
        reader: csv::Reader<File>,
        header: Vec<String>,
        record: csv::StringRecord,
    },
    Jsonl {
        reader: BufReader<File>,
        line: usize,
        text: String,
    },
    Parquet {
        reader: ParquetRecordBatchReader,
        names: Vec<String>,
        batch: Option<RecordBatch>,
        next: usize,
    },
}

impl Rows {
    /// Opens the manifest at `path` in the format its extension names, with its header's
    /// folded names when it is a CSV (every row has every column of its header).
    fn open(path: &Path) -> Result<(Self, Option<Vec<String>>)> {
        let opening = || format!("opening {}", path.display());
        match ext(path).as_str() {
            "csv" | "tsv" => {
                let mut reader = csv::ReaderBuilder::new()
                    .delimiter(if ext(path) == "tsv" { b'\t' } else { b',' })
                    .from_path(path)
                    .with_context(opening)?;
                let header = reader
                    .headers()
                    .with_context(|| format!("reading {}", path.display()))?
                    .clone();
                let names: Vec<&str> = header.iter().collect();
                let header = crate::columns::folded(&names, path, "the header")?;
                let rows = Self::Csv {
                    reader,
                    header: header.clone(),
                    record: csv::StringRecord::new(),
                };
                Ok((rows, Some(header)))
            }
            "jsonl" | "ndjson" => {
                let reader = BufReader::new(File::open(path).with_context(opening)?);
                let text = String::new();
                Ok((
                    Self::Jsonl {
                        reader,
                        line: 0,
                        text,
                    },
                    None,
                ))
            }
            "parquet" => {
                let f = File::open(path).with_context(opening)?;
                let builder = ParquetRecordBatchReaderBuilder::try_new(f)
                    .with_context(|| format!("reading {}", path.display()))?;
                let schema = builder.schema().clone();
                let names: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
                let names = crate::columns::folded(&names, path, "the schema")?;
                let reader = builder
                    .build()
                    .with_context(|| format!("reading {}", path.display()))?;
                let rows = Self::Parquet {
                    reader,
                    names,
                    batch: None,
                    next: 0,
                };
                // No header: a column is the manifest's only where some row has a value there
                // (a value that is text, a number or a boolean), as a JSONL key.
                Ok((rows, None))
            }
            other => bail!(
                "{}: unknown manifest format {other:?} (expected .csv, .jsonl or .parquet)",
                path.display()
            ),
        }
    }

    /// The next row, `None` at the end.
    fn next_row(&mut self, path: &Path) -> Result<Option<BTreeMap<String, String>>> {
        match self {
            Self::Csv {
                reader,
                header,
                record,
            } => {
                let more = reader
                    .read_record(record)
                    .with_context(|| format!("reading {}", path.display()))?;
                Ok(more.then(|| {
                    header
                        .iter()
                        .cloned()
                        .zip(record.iter().map(|v| v.trim().to_string()))
                        .collect()
                }))
            }
            Self::Jsonl { reader, line, text } => next_json_row(reader, line, text, path),
            Self::Parquet {
                reader,
                names,
                batch,
                next,
            } => loop {
                if let Some(b) = batch.as_ref().filter(|b| *next < b.num_rows()) {
                    let row = parquet_row(b, names, *next);
                    *next += 1;
                    return Ok(Some(row));
                }
                match reader.next() {
                    None => return Ok(None),
                    Some(b) => {
                        *batch = Some(b.with_context(|| format!("reading {}", path.display()))?);
                        *next = 0;
                    }
                }
            },
        }
    }
}

/// The next non-blank line of a JSONL manifest as a row (a null value is no value).
fn next_json_row(
    reader: &mut BufReader<File>,
    line: &mut usize,
    text: &mut String,
    path: &Path,
) -> Result<Option<BTreeMap<String, String>>> {
    loop {
        text.clear();
        let n = reader
            .read_line(text)
            .with_context(|| format!("reading {}", path.display()))?;
        if n == 0 {
            return Ok(None);
        }
        *line += 1;
        if text.trim().is_empty() {
            continue;
        }
        let v: serde_json::Map<String, serde_json::Value> = serde_json::from_str(text)
            .with_context(|| format!("{}: line {}", path.display(), line))?;
        let names: Vec<&str> = v.keys().map(String::as_str).collect();
        let keys = crate::columns::folded(&names, path, &format!("line {line}"))?;
        let row = keys
            .into_iter()
            .zip(v.into_iter().map(|(_, v)| v))
            .filter_map(|(k, v)| match v {
                serde_json::Value::String(s) => Some((k, s)),
                serde_json::Value::Null => None,
                other => Some((k, other.to_string())),
            })
            .collect();
        return Ok(Some(row));
    }
}

/// Row `i` of a Parquet batch: text cells, and numbers or booleans in provenance columns.
fn parquet_row(batch: &RecordBatch, names: &[String], i: usize) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    for (name, col) in names.iter().zip(batch.columns()) {
        let known = KNOWN_COLUMNS.contains(&name.as_str()) || PATH_COLUMNS.contains(&name.as_str());
        let value = match string_at(col.as_ref(), i) {
            None if !known => number_at(col.as_ref(), i),
            v => v,
        };
        if let Some(v) = value {
            m.insert(name.clone(), v);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(stream: &mut RowStream, batch: usize) -> Result<Vec<Row>> {
        let mut out = Vec::new();
        loop {
            let rows = stream.next_batch(batch)?;
            if rows.is_empty() {
                return Ok(out);
            }
            out.extend(rows);
        }
    }

    /// Read in batches of 2, a manifest gives the rows `table::read` gives, numbered; a `url`
    /// column is the path column without `--path-column`; a header without rows says so.
    #[test]
    fn batches_are_the_rows_and_url_is_a_path_column() -> Result<()> {
        let dir = tempfile::tempdir()?;
        let csv = dir.path().join("m.csv");
        std::fs::write(
            &csv,
            "url,license\ns3://b/a.glb,cc0\nhttps://h/b.glb,by\n,by\ns3://b/c.glb,\n",
        )?;
        let mut stream = RowStream::open(&csv, None)?;
        assert_eq!(stream.path_column().name, "url");
        let rows = all(&mut stream, 2)?;
        let numbers: Vec<u64> = rows.iter().map(|(n, _)| *n).collect();
        assert_eq!(numbers, [1, 2, 4], "row 3 has no source");
        let said = stream
            .finish()
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            said.contains("1 of 4 rows") && said.contains("row 3: no url"),
            "{said}"
        );
        assert_eq!(rows[1].1.uri, "https://h/b.glb");
        assert_eq!(rows[2].1.extra.get("license").map(String::as_str), Some(""));

        let jsonl = dir.path().join("m.jsonl");
        std::fs::write(
            &jsonl,
            "{\"uri\":\"a.obj\"}\n\n{\"uri\":\"b.obj\",\"tag\":\"t\"}\n",
        )?;
        let mut stream = RowStream::open(&jsonl, None)?;
        let rows = all(&mut stream, 1)?;
        assert_eq!(stream.extra_names(), ["tag"]);
        let tags: Vec<Option<String>> = rows
            .iter()
            .map(|(_, r)| r.extra.get("tag").cloned())
            .collect();
        assert_eq!(tags, [Some(String::new()), Some("t".into())]);

        let empty = dir.path().join("empty.csv");
        std::fs::write(&empty, "uri,id\n")?;
        let mut stream = RowStream::open(&empty, None)?;
        assert!(all(&mut stream, 10)?.is_empty());
        let said = stream
            .finish()
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(said.contains("has no rows"), "{said}");
        // A JSONL or a Parquet file without rows has no header to choose a column from: it
        // is said to have no rows, not to lack a path column.
        let empty = dir.path().join("empty.jsonl");
        std::fs::write(&empty, "\n")?;
        let said = RowStream::open(&empty, None).err().map(|e| e.to_string());
        assert!(
            said.as_deref().is_some_and(|s| s.contains("has no rows")),
            "{said:?}"
        );
        Ok(())
    }
}
