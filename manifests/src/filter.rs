//! `init --where FILTER`: which manifest rows a job takes, chosen when it is frozen. A filter
//! is one or more conditions joined by `and`; a condition compares one column (a provenance
//! column, or `id`, `uri`, `sha256`, `format`) with values, exactly as text:
//!
//! ```text
//! license in (cc-by, cc0)       license = cc0        source != sketchfab
//! license not in ('by-nc', "by-nc-sa") and source = objaverse
//! ```
//!
//! Values are bare words (no spaces, commas or parentheses) or quoted with `'` or `"`. A row
//! without a value in the column holds `""`. A column no row has is refused, naming those
//! there are, so a typo never silently selects nothing.

use crate::table::RawRecord;
use anyhow::{bail, Result};

/// A parsed `--where` filter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Filter {
    conditions: Vec<Condition>,
}

/// `column (=|!=|in|not in) values`.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Condition {
    column: String,
    negated: bool,
    values: Vec<String>,
}

/// A token of a filter: a word (bare or quoted) or a punctuation mark.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Token {
    Word { text: String, quoted: bool },
    Mark(&'static str),
}

/// Splits `text` into words, quoted strings and the marks `(`, `)`, `,`, `=`, `!=`.
fn tokens(text: &str) -> Result<Vec<Token>> {
    let mut out = Vec::new();
    let mut chars = text.chars().peekable();
    while let Some(&c) = chars.peek() {
        match c {
            c if c.is_whitespace() => {
                chars.next();
            }
            '(' | ')' | ',' | '=' => {
                chars.next();
                out.push(Token::Mark(match c {
                    '(' => "(",
                    ')' => ")",
                    ',' => ",",
                    _ => "=",
                }));
            }
            '!' => {
                chars.next();
                if chars.next() != Some('=') {
                    bail!("--where {text:?}: `!` must be followed by `=`");
                }
                out.push(Token::Mark("!="));
            }
            '\'' | '"' => {
                chars.next();
                let mut word = String::new();
                loop {
                    match chars.next() {
                        Some(q) if q == c => break,
                        Some(ch) => word.push(ch),
                        None => bail!("--where {text:?}: a quote {c} is not closed"),
                    }
                }
                out.push(Token::Word {
                    text: word,
                    quoted: true,
                });
            }
            _ => {
                let mut word = String::new();
                while let Some(&ch) = chars.peek() {
                    if ch.is_whitespace() || "(),=!'\"".contains(ch) {
                        break;
                    }
                    word.push(ch);
                    chars.next();
                }
                out.push(Token::Word {
                    text: word,
                    quoted: false,
                });
            }
        }
    }
    Ok(out)
}

/// What a parse error says it found: the token in plain words, or the filter's end.
fn found(t: Option<&Token>) -> String {
    match t {
        None => "the end of the filter".into(),
        Some(Token::Word { text, quoted: true }) => format!("the quoted value {text:?}"),
        Some(Token::Word {
            text,
            quoted: false,
        }) => format!("the word {text:?}"),
        Some(Token::Mark(m)) => format!("`{m}`"),
    }
}

/// Whether `t` is the bare keyword `kw` (any case).
fn is_keyword(t: Option<&Token>, kw: &str) -> bool {
    matches!(t, Some(Token::Word { text, quoted: false }) if text.eq_ignore_ascii_case(kw))
}

/// Reads tokens of one filter in order.
struct Parser<'a> {
    tokens: &'a [Token],
    at: usize,
    text: &'a str,
}

impl Parser<'_> {
    fn next(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.at).cloned();
        self.at += 1;
        t
    }

    fn word(&mut self, what: &str) -> Result<String> {
        match self.next() {
            Some(Token::Word { text, .. }) => Ok(text),
            other => bail!(
                "--where {:?}: expected {what}, found {}",
                self.text,
                found(other.as_ref())
            ),
        }
    }

    fn mark(&mut self, mark: &str) -> Result<()> {
        match self.next() {
            Some(Token::Mark(m)) if m == mark => Ok(()),
            other => bail!(
                "--where {:?}: expected `{mark}`, found {}",
                self.text,
                found(other.as_ref())
            ),
        }
    }

    /// `( v, v, ... )`.
    fn list(&mut self) -> Result<Vec<String>> {
        self.mark("(")?;
        let mut values = vec![self.word("a value")?];
        loop {
            match self.next() {
                Some(Token::Mark(")")) => return Ok(values),
                Some(Token::Mark(",")) => values.push(self.word("a value")?),
                other => bail!(
                    "--where {:?}: expected `,` or `)`, found {}",
                    self.text,
                    found(other.as_ref())
                ),
            }
        }
    }

    fn condition(&mut self) -> Result<Condition> {
        let column = self.word("a column name")?.to_ascii_lowercase();
        let (negated, values) = match self.next() {
            Some(Token::Mark("=")) => (false, vec![self.word("a value")?]),
            Some(Token::Mark("!=")) => (true, vec![self.word("a value")?]),
            t if is_keyword(t.as_ref(), "in") => (false, self.list()?),
            t if is_keyword(t.as_ref(), "not") => {
                let after = self.next();
                if !is_keyword(after.as_ref(), "in") {
                    bail!(
                        "--where {:?}: expected `in` after `not`, found {}",
                        self.text,
                        found(after.as_ref())
                    );
                }
                (true, self.list()?)
            }
            other => bail!(
                "--where {:?}: expected `=`, `!=`, `in` or `not in` after {column}, found {}",
                self.text,
                found(other.as_ref())
            ),
        };
        Ok(Condition {
            column,
            negated,
            values,
        })
    }
}

impl Filter {
    /// Parses a filter as the module describes.
    pub fn parse(text: &str) -> Result<Self> {
        let tokens = tokens(text)?;
        let mut p = Parser {
            tokens: &tokens,
            at: 0,
            text,
        };
        let mut conditions = vec![p.condition()?];
        while p.at < tokens.len() {
            let joint = p.next();
            if !is_keyword(joint.as_ref(), "and") {
                bail!(
                    "--where {text:?}: conditions are joined by `and`, found {}",
                    found(joint.as_ref())
                );
            }
            conditions.push(p.condition()?);
        }
        Ok(Self { conditions })
    }

    /// Whether `record` passes every condition; an error names a column the record lacks.
    fn keeps(&self, record: &RawRecord) -> Option<bool> {
        let mut keep = true;
        for c in &self.conditions {
            let value = record.column(&c.column)?;
            keep &= c.values.iter().any(|v| v == value) != c.negated;
        }
        Some(keep)
    }

    /// The records that pass, in order, and how many were left out. A column that no record
    /// has is refused, naming the manifest's columns.
    pub fn apply(&self, records: Vec<RawRecord>) -> Result<(Vec<RawRecord>, usize)> {
        if let Some(first) = records.first() {
            if let Some(c) = self
                .conditions
                .iter()
                .find(|c| first.column(&c.column).is_none())
            {
                let mut names = vec!["id", "uri", "sha256", "format"];
                names.extend(first.extra.keys().map(String::as_str));
                bail!(
                    "--where: the manifest has no column {:?} (its columns: {})",
                    c.column,
                    names.join(", ")
                );
            }
        }
        let total = records.len();
        let kept: Vec<RawRecord> = records
            .into_iter()
            .filter(|r| self.keeps(r).unwrap_or(false))
            .collect();
        let left_out = total - kept.len();
        Ok((kept, left_out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(license: &str, source: &str) -> RawRecord {
        RawRecord {
            id: Some(format!("{license}-{source}")),
            uri: "/d/a.obj".into(),
            sha256: None,
            format: None,
            extra: [("license", license), ("source", source)]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        }
    }

    fn ids(filter: &str, records: &[RawRecord]) -> Result<(Vec<String>, usize)> {
        let (kept, left_out) = Filter::parse(filter)?.apply(records.to_vec())?;
        Ok((kept.into_iter().filter_map(|r| r.id).collect(), left_out))
    }

    #[test]
    fn conditions_select_rows_by_their_columns() -> Result<()> {
        let rows = [
            record("cc-by", "a"),
            record("cc0", "b"),
            record("by-nc", "a"),
            record("", "b"),
        ];
        assert_eq!(
            ids("license in (cc-by, cc0)", &rows)?,
            (vec!["cc-by-a".into(), "cc0-b".into()], 2)
        );
        assert_eq!(ids("LICENSE = 'cc0'", &rows)?, (vec!["cc0-b".into()], 3));
        assert_eq!(
            ids("license not in (\"by-nc\", '') and source = a", &rows)?,
            (vec!["cc-by-a".into()], 3)
        );
        assert_eq!(ids("source != a", &rows)?.1, 2);
        assert_eq!(ids("license = ''", &rows)?, (vec!["-b".into()], 3));
        assert_eq!(ids("id = cc0-b", &rows)?.0, vec!["cc0-b".to_string()]);
        Ok(())
    }

    #[test]
    fn bad_filters_and_unknown_columns_are_refused() {
        let rows = [record("cc0", "a")];
        for bad in [
            "license",
            "license in cc0",
            "license in (cc0",
            "license = 'cc0",
            "license = cc0 or source = a",
            "license ! cc0",
            "",
        ] {
            assert!(Filter::parse(bad).is_err(), "{bad}");
        }
        // Issue 41, defect 7: what was found is said in words, never as Rust debug text.
        for (bad, said) in [
            ("type license", "after type, found the word \"license\""),
            (
                "license in (cc0 'by')",
                "expected `,` or `)`, found the quoted value \"by\"",
            ),
            ("license in", "expected `(`, found the end of the filter"),
            ("= cc0", "expected a column name, found `=`"),
            (
                "license = cc0 or x = y",
                "joined by `and`, found the word \"or\"",
            ),
            ("license not (cc0)", "expected `in` after `not`, found `(`"),
        ] {
            let e = Filter::parse(bad)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(said), "{bad}: {e}");
            assert!(!e.contains("Some(") && !e.contains("Word {"), "{e}");
        }
        let e = ids("licence = cc0", &rows)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("no column \"licence\"") && e.contains("license, source"),
            "{e}"
        );
    }
}
