//! The PLY parser's error text in words: `ply-rs-bw` formats its causes with Rust's debug
//! notation (`Error: ParseIntError { kind: PosOverflow }`, a grammar error as a struct of
//! line, column and expected tokens, `Version { major: 1, minor: 0 }`) and spreads them over
//! tab-indented lines (issue 64 item 10). [`plain`] keeps the parser's own sentences and the
//! offending text, and says the cause in words.

/// `text` (a `ply-rs-bw` error) on one line, without Rust debug notation.
pub(crate) fn plain(text: &str) -> String {
    // The offending line is quoted with its own newline: `String: '3 0 1 2\n'`.
    let text = text.replace("\n'", "'");
    let mut parts: Vec<String> = Vec::new();
    for line in text.lines() {
        let line = line.trim().trim_end_matches(',').trim();
        if line.is_empty() {
            continue;
        }
        let part = match line.strip_prefix("Error:") {
            Some(cause) => cause_in_words(cause.trim()),
            None if line.contains('{') => format!("{}…", line.split('{').next().unwrap_or("")),
            None => line.to_string(),
        };
        parts.push(part);
    }
    parts.join("; ")
}

/// A parse error's cause, its debug text (after any words before it) as the words a reader
/// needs.
fn cause_in_words(cause: &str) -> String {
    let number = ["ParseIntError", "ParseFloatError"]
        .iter()
        .filter_map(|k| cause.find(k))
        .min();
    if let Some(at) = number {
        let (words, debug) = cause.split_at(at);
        return format!("{words}{}", number_in_words(debug));
    }
    match column(cause) {
        Some(c) => format!("it does not follow the PLY grammar at column {c}"),
        None if cause.contains('{') => "it does not follow the PLY grammar".to_string(),
        None => cause.to_string(),
    }
}

/// `ParseIntError { kind: PosOverflow }` and the like in words.
fn number_in_words(debug: &str) -> &'static str {
    let known = [
        ("PosOverflow", "a number too large for its type"),
        ("NegOverflow", "a number too small for its type"),
        ("InvalidDigit", "not a whole number"),
        ("Empty", "an empty number"),
        ("Zero", "zero where it cannot be"),
    ];
    if debug.starts_with("ParseFloatError") {
        return "not a number";
    }
    known
        .iter()
        .find(|(k, _)| debug.contains(k))
        .map_or("not a whole number", |(_, w)| w)
}

/// The column of a grammar error's debug text (`column: 9`), when it has one.
fn column(cause: &str) -> Option<u64> {
    let rest = &cause[cause.find("column: ")? + "column: ".len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_causes_become_words() {
        let text = "Parse error.\n\tValue: '99999999999'\n\tError: ParseIntError { kind: \
                    PosOverflow }, ";
        assert_eq!(
            plain(text),
            "Parse error.; Value: '99999999999'; a number too large for its type"
        );
        let grammar = "Couldn't parse line.\n\tString: element vertex x\n\tError: ParseError \
                       { location: LineCol { line: 1, column: 16, offset: 15 }, expected: \
                       ExpectedSet { expected: {\"['0' ..= '9']\"} } }";
        let got = plain(grammar);
        assert!(got.ends_with("at column 16"), "{got}");
        assert!(!got.contains('{'), "{got}");
    }
}
