//! The one line an error prints: its causes joined, none repeated.

/// An error and its causes on one line, leaving out a cause whose text the line already
/// holds (typed errors often print their source inside their own message).
pub fn describe(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}
