//! Which column of a manifest holds the paths of its meshes, by one rule (docs/RELIABILITY.md,
//! "Manifests"), never chosen row by row:
//!
//! 1. `--path-column NAME` names it (any column).
//! 2. Otherwise the candidates are the path-like columns (`uri`, `path`, `local_path`, `file`, `url`)
//!    that hold a value in some row. One candidate is the column.
//! 3. With several, a column whose every value is a URL (`scheme://…`) is left out: a
//!    manifest with URLs and local copies converts the copies (`--path-column uri` fetches
//!    the URLs instead). When one is left it is the column, otherwise the manifest is
//!    refused, naming the candidates, until `--path-column` says which.
//!
//! Every row must then hold a source in that column: a local path or a URL of a scheme
//! sparc3d fetches (`sparc3d_sources::location`). A row with none there (empty, or a value
//! only in another path-like column) or with a URL no worker could read (an unknown scheme,
//! credentials in it, ...) is refused, naming the row.

use crate::problems::Problems;
use crate::record::PATH_COLUMNS;
use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// The column chosen and why, for `init` to say.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PathColumn {
    /// The column's name (lower case, as the manifest reader keys rows).
    pub name: String,
    /// Why this one: `given`, the only path-like column, or the others hold URLs.
    pub why: String,
}

pub use sparc3d_sources::location::is_url;

/// Which columns of a manifest hold values, as [`choose_from`] needs to know: the path-like
/// columns with a value in some row, and those with a value that is not a URL.
#[derive(Debug, Clone, Default)]
pub struct ValueSurvey {
    /// Columns with a value in some row.
    pub has_value: std::collections::BTreeSet<String>,
    /// Columns with a value that is not a URL in some row.
    pub not_only_urls: std::collections::BTreeSet<String>,
}

impl ValueSurvey {
    /// Counts one row's values in.
    pub fn add(&mut self, row: &BTreeMap<String, String>) {
        for (name, value) in row.iter().filter(|(_, v)| !v.is_empty()) {
            if !self.has_value.contains(name) {
                self.has_value.insert(name.clone());
            }
            if !is_url(value) && !self.not_only_urls.contains(name) {
                self.not_only_urls.insert(name.clone());
            }
        }
    }
}

/// The path column of `rows` (keys in lower case) by the module's rule; `given` is
/// `--path-column`. `source` names the manifest in errors.
pub fn choose(
    rows: &[BTreeMap<String, String>],
    given: Option<&str>,
    source: &Path,
) -> Result<PathColumn> {
    let mut survey = ValueSurvey::default();
    rows.iter().for_each(|r| survey.add(r));
    choose_from(&survey, given, source)
}

/// [`choose`] from what a pass over the rows found.
pub fn choose_from(survey: &ValueSurvey, given: Option<&str>, source: &Path) -> Result<PathColumn> {
    let has_value = |col: &str| survey.has_value.contains(col);
    if let Some(name) = given {
        let name = name.trim().to_ascii_lowercase();
        if !has_value(&name) {
            return Err(no_value_in(&name, source));
        }
        return Ok(given_column(name));
    }
    let candidates: Vec<&str> = PATH_COLUMNS.into_iter().filter(|c| has_value(c)).collect();
    let local: Vec<&str> = candidates
        .iter()
        .copied()
        .filter(|c| survey.not_only_urls.contains(*c))
        .collect();
    match (candidates.as_slice(), local.as_slice()) {
        ([], _) => Err(no_path_column(source)),
        ([only], _) => Ok(only_column(only)),
        (_, [one]) => {
            let urls: Vec<&str> = candidates.iter().copied().filter(|c| c != one).collect();
            Ok(PathColumn {
                name: one.to_string(),
                why: format!(
                    "{} holds only URLs, so the local copies are read; --path-column {} \
                     fetches the URLs instead",
                    urls.join(" and "),
                    urls.first().copied().unwrap_or("uri")
                ),
            })
        }
        (_, []) => bail!(
            "{}: several path columns hold URLs ({}); say which to fetch with --path-column NAME",
            source.display(),
            candidates.join(", ")
        ),
        _ => bail!(
            "{}: several path columns hold local paths ({}); say which with --path-column NAME",
            source.display(),
            local.join(", ")
        ),
    }
}

/// The column `--path-column` named (folded).
pub fn given_column(name: String) -> PathColumn {
    PathColumn {
        name,
        why: "given with --path-column".into(),
    }
}

/// The only path-like column.
pub fn only_column(name: &str) -> PathColumn {
    PathColumn {
        name: name.to_string(),
        why: "the only path column".into(),
    }
}

/// The refusal of `--path-column name` when no row has a value there.
pub fn no_value_in(name: &str, source: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: --path-column {name}: no row has a value in a column of that name",
        source.display()
    )
}

/// The refusal of a manifest without a path-like column holding a value.
pub fn no_path_column(source: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: no path column (expected a column named one of {}, or --path-column NAME)",
        source.display(),
        PATH_COLUMNS.join(", ")
    )
}

/// Why `row` has no source in `column` (a local path, or a URL a worker can fetch); `None`
/// when it has one.
pub fn row_problem(row: &BTreeMap<String, String>, column: &PathColumn) -> Option<String> {
    let value = row.get(&column.name).map(String::as_str).unwrap_or("");
    if value.is_empty() {
        let others: Vec<(&str, &String)> = PATH_COLUMNS
            .into_iter()
            .filter(|c| *c != column.name)
            .filter_map(|c| Some((c, row.get(c).filter(|v| !v.is_empty())?)))
            .collect();
        let names = others
            .iter()
            .map(|(c, _)| *c)
            .collect::<Vec<_>>()
            .join(", ");
        return Some(if others.is_empty() {
            format!("no {}", column.name)
        } else if others.iter().all(|(_, v)| is_url(v)) {
            format!("no {}, only a URL in {names}", column.name)
        } else {
            format!(
                "no {}, only a path in {names} (ambiguous: say which with --path-column)",
                column.name
            )
        });
    }
    let parsed = sparc3d_sources::Location::parse(value);
    parsed.err().map(|e| format!("{}: {e}", column.name))
}

/// Rows without a readable source named in full by [`rows_refusal`]; the rest are counted.
pub const LISTED_ROWS: usize = 10;

/// The refusal of a manifest whose rows `bad` (as `row N: why`, of `total` rows) have no
/// readable source in `column`.
pub fn rows_refusal(
    source: &Path,
    column: &PathColumn,
    bad: &Problems,
    total: u64,
) -> anyhow::Error {
    anyhow::anyhow!(
        "{}: {} of {total} rows have no readable source in column {} ({}): {}{}",
        source.display(),
        bad.count(),
        column.name,
        column.why,
        bad.listed().join("; "),
        if bad.count() > LISTED_ROWS as u64 {
            "; …"
        } else {
            ""
        }
    )
}

/// Refuses rows without a source in `column` (a local path, or a URL a worker can fetch),
/// naming the first few and how many.
pub fn check_rows(
    rows: &[BTreeMap<String, String>],
    column: &PathColumn,
    source: &Path,
) -> Result<()> {
    let mut bad = Problems::default();
    for (n, row) in rows.iter().enumerate() {
        if let Some(why) = row_problem(row, column) {
            bad.add(|| format!("row {}: {why}", n + 1), LISTED_ROWS);
        }
    }
    if bad.count() == 0 {
        return Ok(());
    }
    Err(rows_refusal(source, column, &bad, rows.len() as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(list: &[&[(&str, &str)]]) -> Vec<BTreeMap<String, String>> {
        list.iter()
            .map(|r| {
                r.iter()
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect()
            })
            .collect()
    }

    #[test]
    fn urls_are_told_from_paths() {
        for url in [
            "s3://b/x.obj",
            "https://h/x.obj",
            "file:///x.obj",
            "gs+x-y.z://a",
        ] {
            assert!(is_url(url), "{url}");
        }
        for path in [
            "/data/x.obj",
            "x.obj",
            "a/b://c.obj",
            "://x",
            "1s3://x",
            "C:/x.obj",
        ] {
            assert!(!is_url(path), "{path}");
        }
    }

    #[test]
    fn one_rule_for_the_column() -> Result<()> {
        let m = Path::new("m.csv");
        let both = rows(&[
            &[("uri", "s3://b/a.obj"), ("local_path", "/d/a.obj")],
            &[("uri", "s3://b/b.obj"), ("local_path", "/d/b.obj")],
        ]);
        let c = choose(&both, None, m)?;
        assert_eq!(c.name, "local_path");
        assert!(c.why.contains("uri holds only URLs"), "{}", c.why);
        assert_eq!(choose(&both, Some("URI"), m)?.name, "uri");
        let two_local = rows(&[&[("path", "/d/a.obj"), ("local_path", "/e/a.obj")]]);
        let e = choose(&two_local, None, m).err().map(|e| e.to_string());
        assert!(
            e.as_deref()
                .is_some_and(|e| e.contains("path, local_path") && e.contains("--path-column")),
            "{e:?}"
        );
        let only = rows(&[&[("file", "a.obj"), ("id", "x")]]);
        assert_eq!(choose(&only, None, m)?.name, "file");
        assert!(choose(&rows(&[&[("id", "x")]]), None, m).is_err());
        assert!(choose(&only, Some("nope"), m).is_err());
        Ok(())
    }

    #[test]
    fn rows_without_a_local_path_in_the_column_are_refused() -> Result<()> {
        let m = Path::new("m.csv");
        let r = rows(&[
            &[("uri", "s3://b/a.obj"), ("local_path", "/d/a.obj")],
            &[("uri", "s3://b/b.obj"), ("local_path", "")],
            &[("uri", ""), ("local_path", "ftp://h/c.obj")],
            &[("uri", ""), ("local_path", "https://h/d.obj")],
        ]);
        let c = PathColumn {
            name: "local_path".into(),
            why: "given".into(),
        };
        let e = check_rows(&r, &c, m)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("2 of 4 rows"), "{e}");
        assert!(e.contains("row 2: no local_path, only a URL in uri"), "{e}");
        assert!(
            e.contains("row 3: local_path: ftp://h/c.obj: unknown scheme"),
            "{e}"
        );
        assert!(!e.contains("row 4"), "a fetchable URL is a source: {e}");
        let r = rows(&[&[("path", "/d/a.obj"), ("local_path", "")]]);
        let e = check_rows(&r, &c, m)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("row 1: no local_path, only a path in path (ambiguous"),
            "{e}"
        );
        check_rows(&rows(&[&[("local_path", "/d/a.obj")]]), &c, m)
    }
}
