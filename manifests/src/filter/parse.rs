//! The grammar of a `--where` filter: tokens, then conditions joined by `and`.
//!
//! ```text
//! filter    := condition ( "and" condition )*          ("and", "in", "not": any case)
//! condition := column OP value | column ["not"] "in" "(" value ( "," value )* ")"
//! OP        := "=" | "!=" | "<" | "<=" | ">" | ">="
//! value     := bare word (no space, comma, parenthesis, quote, "=", "!", "<", ">")
//!            | 'quoted' | "quoted"
//! ```
//!
//! `<`, `<=`, `>`, `>=` need a number on the right; that is checked here, where the filter is
//! read. Whether the column is there and numeric is the table's to say ([`super::Filter`]).

use anyhow::{bail, Result};

/// How a condition compares its column with its values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// `=` (one value) or `in (...)`: equal to one of the values.
    In,
    /// `!=` (one value) or `not in (...)`: equal to none of them.
    NotIn,
    /// `<`.
    Lt,
    /// `<=`.
    Le,
    /// `>`.
    Gt,
    /// `>=`.
    Ge,
}

impl Op {
    /// The operator as written (`in`/`not in` for the list forms).
    pub fn symbol(self) -> &'static str {
        match self {
            Op::In => "=",
            Op::NotIn => "!=",
            Op::Lt => "<",
            Op::Le => "<=",
            Op::Gt => ">",
            Op::Ge => ">=",
        }
    }

    /// Whether the operator orders numbers (`<`, `<=`, `>`, `>=`).
    pub fn is_ordering(self) -> bool {
        !matches!(self, Op::In | Op::NotIn)
    }
}

/// `column OP values`: one value for the comparisons, one or more for `in`.
#[derive(Debug, Clone, PartialEq)]
pub struct Condition {
    /// The column, lower-cased.
    pub column: String,
    /// The comparison.
    pub op: Op,
    /// The values as written (without quotes).
    pub values: Vec<String>,
    /// The value as a number, for the ordering operators.
    pub number: Option<f64>,
}

/// A token of a filter: a word (bare or quoted) or a punctuation mark.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Token {
    Word { text: String, quoted: bool },
    Mark(&'static str),
}

/// The marks of one character, and those that may be followed by `=`.
fn mark(c: char, next: Option<char>) -> Option<&'static str> {
    Some(match (c, next) {
        ('(', _) => "(",
        (')', _) => ")",
        (',', _) => ",",
        ('=', _) => "=",
        ('!', Some('=')) => "!=",
        ('<', Some('=')) => "<=",
        ('>', Some('=')) => ">=",
        ('<', _) => "<",
        ('>', _) => ">",
        _ => return None,
    })
}

/// Characters that end a bare word.
const STOPS: &str = "(),=!<>'\"";

/// Splits `text` into words, quoted strings and the marks `(`, `)`, `,`, `=`, `!=`, `<`,
/// `<=`, `>`, `>=`.
fn tokens(text: &str) -> Result<Vec<Token>> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut at = 0;
    while let Some(&c) = chars.get(at) {
        if c.is_whitespace() {
            at += 1;
        } else if let Some(m) = mark(c, chars.get(at + 1).copied()) {
            at += m.len();
            out.push(Token::Mark(m));
        } else if c == '!' {
            bail!("--where {text:?}: `!` must be followed by `=`");
        } else if c == '\'' || c == '"' {
            let Some(len) = chars[at + 1..].iter().position(|&q| q == c) else {
                bail!("--where {text:?}: a quote {c} is not closed");
            };
            let word = chars[at + 1..at + 1 + len].iter().collect();
            out.push(Token::Word {
                text: word,
                quoted: true,
            });
            at += len + 2;
        } else {
            let len = chars[at..]
                .iter()
                .position(|&ch| ch.is_whitespace() || STOPS.contains(ch))
                .unwrap_or(chars.len() - at);
            out.push(Token::Word {
                text: chars[at..at + len].iter().collect(),
                quoted: false,
            });
            at += len;
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

/// A value as a number, as the ordering operators and numeric columns read it: a decimal
/// number (`1000000`, `0.5`, `-3`, `1e6`, `inf`); not NaN, which orders with nothing.
pub fn number(value: &str) -> Option<f64> {
    value.trim().parse::<f64>().ok().filter(|x| !x.is_nan())
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

    /// The number after an ordering operator; an error names the value that is not one.
    fn ordered(&mut self, column: &str, op: Op) -> Result<(Op, Vec<String>)> {
        let value = self.word("a number")?;
        if number(&value).is_none() {
            bail!(
                "--where {:?}: `{column} {} {value}`: {value:?} is not a number ({} compares \
                 numbers)",
                self.text,
                op.symbol(),
                op.symbol()
            );
        }
        Ok((op, vec![value]))
    }

    fn condition(&mut self) -> Result<Condition> {
        let column = self.word("a column name")?.to_ascii_lowercase();
        let (op, values) = match self.next() {
            Some(Token::Mark("=")) => (Op::In, vec![self.word("a value")?]),
            Some(Token::Mark("!=")) => (Op::NotIn, vec![self.word("a value")?]),
            Some(Token::Mark("<")) => self.ordered(&column, Op::Lt)?,
            Some(Token::Mark("<=")) => self.ordered(&column, Op::Le)?,
            Some(Token::Mark(">")) => self.ordered(&column, Op::Gt)?,
            Some(Token::Mark(">=")) => self.ordered(&column, Op::Ge)?,
            t if is_keyword(t.as_ref(), "in") => (Op::In, self.list()?),
            t if is_keyword(t.as_ref(), "not") => {
                let after = self.next();
                if !is_keyword(after.as_ref(), "in") {
                    bail!(
                        "--where {:?}: expected `in` after `not`, found {}",
                        self.text,
                        found(after.as_ref())
                    );
                }
                (Op::NotIn, self.list()?)
            }
            other => bail!(
                "--where {:?}: expected `=`, `!=`, `<`, `<=`, `>`, `>=`, `in` or `not in` after \
                 {column}, found {}",
                self.text,
                found(other.as_ref())
            ),
        };
        let number = op.is_ordering().then(|| number(&values[0])).flatten();
        Ok(Condition {
            column,
            op,
            values,
            number,
        })
    }
}

/// Parses a filter's conditions as the module describes.
pub fn conditions(text: &str) -> Result<Vec<Condition>> {
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
    Ok(conditions)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comparisons_read_their_operator_and_number() -> Result<()> {
        let c = conditions("input_faces<=1e6 and aspect > 2.5 AND x >= -1 and y<3")?;
        let ops: Vec<(Op, Option<f64>)> = c.iter().map(|c| (c.op, c.number)).collect();
        assert_eq!(
            ops,
            [
                (Op::Le, Some(1e6)),
                (Op::Gt, Some(2.5)),
                (Op::Ge, Some(-1.0)),
                (Op::Lt, Some(3.0))
            ]
        );
        let c = conditions("license in (cc0, 'cc by') and n = 3")?;
        assert_eq!((c[0].op, c[0].values.len()), (Op::In, 2));
        assert_eq!((c[1].op, c[1].number), (Op::In, None));
        Ok(())
    }

    #[test]
    fn an_ordering_needs_a_number_and_says_which_value_is_not() {
        for (bad, said) in [
            ("input_faces < many", "\"many\" is not a number"),
            ("input_faces <= 'ten'", "\"ten\" is not a number"),
            ("aspect > nan", "\"nan\" is not a number"),
            ("aspect >", "expected a number, found the end of the filter"),
            ("aspect < (1, 2)", "expected a number, found `(`"),
            ("a => 3", "expected a value, found `>`"),
        ] {
            let e = conditions(bad)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(said), "{bad}: {e}");
        }
    }
}
