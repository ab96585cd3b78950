//! The AWS shared credentials file, which `object_store` does not read: when no access key is
//! in the environment, the profile `AWS_PROFILE` (or `default`) of
//! `AWS_SHARED_CREDENTIALS_FILE` (or `~/.aws/credentials`) gives the key, the secret and the
//! session token. Nothing from it is printed or stored.

use std::collections::HashMap;
use std::path::PathBuf;

/// The `aws_*` keys of the profile in use, when the environment has no access key and the
/// file has the profile; empty otherwise.
pub(crate) fn credentials() -> HashMap<String, String> {
    if std::env::var_os("AWS_ACCESS_KEY_ID").is_some() {
        return HashMap::new();
    }
    let file = match std::env::var_os("AWS_SHARED_CREDENTIALS_FILE") {
        Some(f) => PathBuf::from(f),
        None => match std::env::var_os("HOME") {
            Some(home) => PathBuf::from(home).join(".aws").join("credentials"),
            None => return HashMap::new(),
        },
    };
    let profile = std::env::var("AWS_PROFILE").unwrap_or_else(|_| "default".into());
    match std::fs::read_to_string(file) {
        Ok(text) => section(&text, &profile),
        Err(_) => HashMap::new(),
    }
}

/// The keys of INI section `[name]` in `text`, lower-cased, limited to the credential keys.
fn section(text: &str, name: &str) -> HashMap<String, String> {
    let mut out = HashMap::new();
    let mut inside = false;
    for line in text.lines().map(str::trim) {
        if let Some(header) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            inside = header.trim() == name;
            continue;
        }
        let Some((key, value)) = line.split_once('=').filter(|_| inside) else {
            continue;
        };
        let key = key.trim().to_ascii_lowercase();
        if matches!(
            key.as_str(),
            "aws_access_key_id" | "aws_secret_access_key" | "aws_session_token"
        ) {
            out.insert(key, value.trim().to_string());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_named_profile_gives_its_keys_only() {
        let text = "[default]\naws_access_key_id = A\naws_secret_access_key=B\n\n\
                    [other]\naws_access_key_id = C\naws_secret_access_key = D\nregion = x\n";
        let other = super::section(text, "other");
        assert_eq!(
            other.get("aws_access_key_id").map(String::as_str),
            Some("C")
        );
        assert_eq!(
            other.get("aws_secret_access_key").map(String::as_str),
            Some("D")
        );
        assert_eq!(other.len(), 2);
        assert!(super::section(text, "missing").is_empty());
    }
}
