//! The fields of the tab-separated lines `ls` and `failures` print. A field's backslash, tab,
//! newline and carriage return are written `\\`, `\t`, `\n` and `\r`, and any other ASCII
//! control character `\xNN` (two hex digits), so every item is one line of the same fields
//! whatever its id, path or message holds; undo it with the same rules to get the text back.
//! These are the escapes of PostgreSQL's `COPY ... (FORMAT text)` (its documentation, "COPY",
//! "Text Format"), which `psql`, pandas (`escapechar`) and most TSV tools follow.

use std::borrow::Cow;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controls_and_backslashes_are_escaped_and_the_rest_kept() {
        assert!(matches!(field("/data/chair 1/椅子.obj"), Cow::Borrowed(_)));
        assert_eq!(
            field("a\tb\nc\rd\\e\u{1}f\u{7f}"),
            "a\\tb\\nc\\rd\\\\e\\x01f\\x7F"
        );
    }
}
