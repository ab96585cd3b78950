//! The fields of the tab-separated lines `ls` and `failures` print. A field's backslash, tab,
//! newline and carriage return are written `\\`, `\t`, `\n` and `\r`, and any other ASCII
//! control character `\xNN` (two hex digits), so every item is one line of the same fields
//! whatever its id, path or message holds; undo it with the same rules to get the text back.
//! These are the escapes of PostgreSQL's `COPY ... (FORMAT text)` (its documentation, "COPY",
//! "Text Format"), which `psql`, pandas (`escapechar`) and most TSV tools follow.
//!
//! An item's provenance columns follow its fixed fields as `name=value` fields, in name order
//! ([`provenance`]), so a line says which column each value is from without a header.

use std::borrow::Cow;
use std::collections::BTreeMap;

/// `text` as one field: escaped as the module says, borrowed when nothing needs escaping.
pub fn field(text: &str) -> Cow<'_, str> {
    if !text.chars().any(|c| c == '\\' || c.is_ascii_control()) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            c if c.is_ascii_control() => out.push_str(&format!("\\x{:02X}", c as u32)),
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// An item's provenance columns as trailing fields: `\tname=value` for each, in name order,
/// escaped as [`field`] does; empty when it has none.
pub fn provenance(extra: &BTreeMap<String, String>) -> String {
    extra
        .iter()
        .map(|(name, value)| format!("\t{}={}", field(name), field(value)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn provenance_fields_name_their_column() {
        let extra: BTreeMap<String, String> = [("name", "a\tb"), ("license", "cc0"), ("tags", "")]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        assert_eq!(provenance(&extra), "\tlicense=cc0\tname=a\\tb\ttags=");
        assert_eq!(provenance(&BTreeMap::new()), "");
    }

    #[test]
    fn controls_and_backslashes_are_escaped_and_the_rest_kept() {
        assert!(matches!(field("/data/chair 1/椅子.obj"), Cow::Borrowed(_)));
        assert_eq!(
            field("a\tb\nc\rd\\e\u{1}f\u{7f}"),
            "a\\tb\\nc\\rd\\\\e\\x01f\\x7F"
        );
    }
}
