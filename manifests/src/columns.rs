//! A manifest's column names as the reader keys rows: trimmed and lower-cased, so `Path`,
//! `URI` and `License` are the columns `path`, `uri` and `license`. Two columns whose names
//! are one name once folded (`Licence` and `licence`; `id` and `ID`; a name given twice) are
//! refused, naming both as written: keeping one would drop the other's values silently, and an
//! id or a path could come from a column other than the one `init` names.

use anyhow::{bail, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// The name a column is read by: trimmed, in lower case.
pub fn fold(name: &str) -> String {
    name.trim().to_ascii_lowercase()
}

/// The folded names of `names` (one table's header, or one JSONL line's keys), in order;
/// refused when two of them fold to one name. `source` names the manifest, `place` where in
/// it the names are (`"the header"`, `"line 3"`).
pub fn folded(names: &[&str], source: &Path, place: &str) -> Result<Vec<String>> {
    let mut seen: BTreeMap<String, &str> = BTreeMap::new();
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let key = fold(name);
        if let Some(first) = seen.insert(key.clone(), name) {
            let how = if first == *name {
                format!("column {name:?} appears twice")
            } else {
                format!(
                    "columns {first:?} and {name:?} are one column, {key:?}, once case and \
                     spaces are ignored"
                )
            };
            bail!(
                "{}: {place}: {how} (column names are read without case); rename or drop one \
                 of them so each column has a name of its own",
                source.display()
            );
        }
        out.push(key);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(names: &[&str]) -> String {
        folded(names, Path::new("m.csv"), "the header")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    }

    #[test]
    fn names_that_fold_to_one_are_refused_naming_both() -> Result<()> {
        assert_eq!(
            folded(
                &[" Path", "ID", "License"],
                Path::new("m.csv"),
                "the header"
            )?,
            ["path", "id", "license"]
        );
        let e = refusal(&["Licence", "licence"]);
        assert!(
            e.contains("\"Licence\" and \"licence\"") && e.contains("the header"),
            "{e}"
        );
        let e = refusal(&["id", "uri", "sha256", "ID", "Uri"]);
        assert!(e.contains("\"id\" and \"ID\""), "{e}");
        let e = refusal(&["uri", "name", "name"]);
        assert!(e.contains("\"name\" appears twice"), "{e}");
        Ok(())
    }
}
