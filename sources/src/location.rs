//! What a manifest's `uri` names: a local file, or a remote object by scheme. One parser for
//! `init` (which refuses what no worker could read, naming the row) and for the worker.

use std::fmt;
use std::path::PathBuf;
use url::Url;

/// The remote schemes read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Scheme {
    /// `http://host[:port]/path`.
    Http,
    /// `https://host[:port]/path`.
    Https,
    /// `s3://bucket/key`: Amazon S3 or an S3-compatible store.
    S3,
    /// `gs://bucket/key`: Google Cloud Storage.
    Gs,
    /// `az://container/path`: Azure Blob Storage.
    Az,
}

impl Scheme {
    /// The scheme as written in URLs.
    pub fn as_str(self) -> &'static str {
        match self {
            Scheme::Http => "http",
            Scheme::Https => "https",
            Scheme::S3 => "s3",
            Scheme::Gs => "gs",
            Scheme::Az => "az",
        }
    }

    fn parse(s: &str) -> Option<Scheme> {
        Some(match s {
            "http" => Scheme::Http,
            "https" => Scheme::Https,
            "s3" => Scheme::S3,
            "gs" => Scheme::Gs,
            "az" => Scheme::Az,
            _ => return None,
        })
    }

    /// Whether objects are addressed as `bucket/key` (not an HTTP origin and path).
    pub fn is_bucket(self) -> bool {
        matches!(self, Scheme::S3 | Scheme::Gs | Scheme::Az)
    }
}

/// The schemes a manifest's `uri` may have, for messages.
pub const SCHEMES: &str = "file://, http://, https://, s3://, gs://, az://";

/// A remote object: its scheme, its bucket (or HTTP origin) and its key.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct RemoteUrl {
    /// The scheme.
    pub scheme: Scheme,
    url: Url,
}

/// A parsed `uri`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A file on this machine (a plain path, or a `file://` URL decoded).
    Local(PathBuf),
    /// An object fetched over the network.
    Remote(RemoteUrl),
}

/// Why a `uri` names nothing sparc3d can read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{uri}: {reason}")]
pub struct LocationError {
    /// The uri as given (credentials in it cut out).
    pub uri: String,
    /// What is wrong with it.
    pub reason: String,
}

/// Whether `value` starts with a URL scheme (`scheme://`, the scheme a letter then letters,
/// digits, `+`, `-` or `.`, as RFC 3986 §3.1 spells it) rather than being a local path.
pub fn is_url(value: &str) -> bool {
    scheme_of(value).is_some()
}

fn scheme_of(value: &str) -> Option<&str> {
    let (scheme, _) = value.split_once("://")?;
    let mut chars = scheme.chars();
    let ok = chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'));
    ok.then_some(scheme)
}

impl Location {
    /// Parses a manifest's `uri`. A value without `scheme://` is a local path; `file://` is
    /// decoded to one; `http`, `https`, `s3`, `gs` and `az` are remote. Refused: any other
    /// scheme, a bucket URL without a bucket or a key, an HTTP URL with a query or fragment
    /// (objects are addressed by path), and credentials inside the URL (they would be
    /// stored in the job's files and printed in messages: give them in the environment).
    pub fn parse(uri: &str) -> Result<Location, LocationError> {
        let Some(scheme) = scheme_of(uri) else {
            return Ok(Location::Local(PathBuf::from(uri)));
        };
        let lower = scheme.to_ascii_lowercase();
        let err = |reason: String| LocationError {
            uri: redact(uri),
            reason,
        };
        if lower == "file" {
            let url = Url::parse(uri).map_err(|e| err(format!("not a valid file URL: {e}")))?;
            return url
                .to_file_path()
                .map(Location::Local)
                .map_err(|_| err("not a local absolute file URL (file:///path)".into()));
        }
        let Some(scheme) = Scheme::parse(&lower) else {
            return Err(err(format!(
                "unknown scheme `{scheme}://` (sparc3d reads local paths and {SCHEMES})"
            )));
        };
        let url = Url::parse(uri).map_err(|e| err(format!("not a valid URL: {e}")))?;
        if !url.username().is_empty() || url.password().is_some() {
            return Err(err(
                "credentials inside the URL are refused (they would be written into the job's \
                 files and logs): give them in the environment (docs/CLUSTER.md, \"Remote \
                 sources\")"
                    .into(),
            ));
        }
        if url.host_str().is_none_or(str::is_empty) {
            let what = if scheme.is_bucket() { "bucket" } else { "host" };
            return Err(err(format!("no {what} in the URL")));
        }
        if url.query().is_some() || url.fragment().is_some() {
            return Err(err(
                "a query or fragment is not supported (objects are addressed by their path)".into(),
            ));
        }
        let remote = RemoteUrl { scheme, url };
        if remote.key().is_empty() {
            return Err(err("no object key or path after the host".into()));
        }
        Ok(Location::Remote(remote))
    }

    /// The remote object, if this is one.
    pub fn remote(&self) -> Option<&RemoteUrl> {
        match self {
            Location::Remote(r) => Some(r),
            Location::Local(_) => None,
        }
    }
}

/// `uri` with any `user:password@` cut out, for messages.
fn redact(uri: &str) -> String {
    match Url::parse(uri) {
        Ok(mut url) if !url.username().is_empty() || url.password().is_some() => {
            let _ = url.set_username("");
            let _ = url.set_password(None);
            url.to_string()
        }
        _ => uri.to_string(),
    }
}

impl RemoteUrl {
    /// A prefix to list (`s3://bucket/prefix/`, possibly only `s3://bucket`): like
    /// [`Location::parse`], but the key may be empty. HTTP has no listing.
    pub fn parse_prefix(uri: &str) -> Result<RemoteUrl, LocationError> {
        let err = |reason: &str| LocationError {
            uri: redact(uri),
            reason: reason.into(),
        };
        let with_key = if uri.ends_with('/') {
            format!("{uri}_")
        } else {
            format!("{uri}/_")
        };
        match Location::parse(&with_key)? {
            Location::Remote(mut r) if r.scheme.is_bucket() => {
                let key = r.key();
                let prefix = key.strip_suffix('_').unwrap_or(&key).to_string();
                r.url.set_path(&format!("/{prefix}"));
                Ok(r)
            }
            Location::Remote(_) => Err(err(
                "HTTP servers cannot be listed: list the files in a manifest (a CSV with a uri \
                 column of URLs)",
            )),
            Location::Local(_) => Err(err("not a bucket URL")),
        }
    }

    /// The bucket (container) name, or for HTTP the origin `host[:port]`.
    pub fn bucket(&self) -> String {
        let host = self.url.host_str().unwrap_or_default();
        match self.url.port() {
            Some(port) => format!("{host}:{port}"),
            None => host.to_string(),
        }
    }

    /// The object key (the URL's path without its leading `/`), percent-decoded.
    pub fn key(&self) -> String {
        let path = self.url.path().trim_start_matches('/');
        percent_decode(path)
    }

    /// The URL of the object at `relative` (a path of plain components, already checked:
    /// no `..`, not absolute) next to this one, i.e. under this object's own prefix. glTF
    /// buffers are found this way.
    pub fn sibling(&self, relative: &str) -> RemoteUrl {
        let mut url = self.url.clone();
        if let Ok(mut segments) = url.path_segments_mut() {
            segments.pop();
            for part in relative.split('/').filter(|p| !p.is_empty() && *p != ".") {
                segments.push(part);
            }
        }
        RemoteUrl {
            scheme: self.scheme,
            url,
        }
    }

    /// The object at `key` in the same bucket (for listings).
    pub fn with_key(&self, key: &str) -> RemoteUrl {
        let mut url = self.url.clone();
        if let Ok(mut segments) = url.path_segments_mut() {
            segments.clear();
            for part in key.split('/') {
                segments.push(part);
            }
        }
        RemoteUrl {
            scheme: self.scheme,
            url,
        }
    }
}

impl fmt::Display for RemoteUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.url.as_str())
    }
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = (b[i] == b'%')
            .then(|| b.get(i + 1..i + 3))
            .flatten()
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match hex {
            Some(byte) => {
                out.push(byte);
                i += 3;
            }
            None => {
                out.push(b[i]);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn remote(uri: &str) -> RemoteUrl {
        match Location::parse(uri) {
            Ok(Location::Remote(r)) => r,
            other => panic!("{uri}: {other:?}"),
        }
    }

    #[test]
    fn paths_files_and_remote_objects_are_told_apart() {
        assert_eq!(
            Location::parse("/data/a.obj"),
            Ok(Location::Local("/data/a.obj".into()))
        );
        assert_eq!(
            Location::parse("rel/a b.obj"),
            Ok(Location::Local("rel/a b.obj".into()))
        );
        assert_eq!(
            Location::parse("file:///data/a%20b.obj"),
            Ok(Location::Local("/data/a b.obj".into()))
        );
        let s3 = remote("s3://bucket/meshes/a b.glb");
        assert_eq!((s3.scheme, s3.bucket()), (Scheme::S3, "bucket".into()));
        assert_eq!(s3.key(), "meshes/a b.glb");
        let http = remote("http://127.0.0.1:8080/m/x%20y.obj");
        assert_eq!(http.bucket(), "127.0.0.1:8080");
        assert_eq!(http.key(), "m/x y.obj");
        assert_eq!(remote("gs://b/k.ply").scheme, Scheme::Gs);
        assert_eq!(remote("az://c/k.ply").scheme, Scheme::Az);
    }

    #[test]
    fn what_no_worker_could_read_is_refused_with_the_reason() {
        let reason = |uri: &str| match Location::parse(uri) {
            Err(e) => e.to_string(),
            Ok(l) => panic!("{uri} parsed as {l:?}"),
        };
        assert!(reason("ftp://h/a.obj").contains("unknown scheme `ftp://`"));
        assert!(reason("s3://bucket").contains("no object key"));
        assert!(reason("https://h/a.glb?sig=1").contains("query"));
        let secret = reason("https://user:hunter2@h/a.glb");
        assert!(secret.contains("credentials inside the URL"), "{secret}");
        assert!(!secret.contains("hunter2"), "{secret}");
        assert!(reason("file://host/a.obj").contains("file URL"));
    }

    #[test]
    fn siblings_stay_under_the_objects_own_prefix() {
        let gltf = remote("s3://b/scenes/one/scene.gltf");
        assert_eq!(
            gltf.sibling("bufs/scene 0.bin").to_string(),
            "s3://b/scenes/one/bufs/scene%200.bin"
        );
        assert_eq!(
            gltf.sibling("bufs/scene 0.bin").key(),
            "scenes/one/bufs/scene 0.bin"
        );
        let http = remote("http://h:1/a/b.gltf");
        assert_eq!(http.sibling("./b.bin").to_string(), "http://h:1/a/b.bin");
    }

    #[test]
    fn prefixes_list_buckets_not_http_servers() -> Result<(), LocationError> {
        let p = RemoteUrl::parse_prefix("s3://bucket/meshes/")?;
        assert_eq!((p.bucket(), p.key()), ("bucket".into(), "meshes/".into()));
        assert_eq!(RemoteUrl::parse_prefix("s3://bucket")?.key(), "");
        assert!(RemoteUrl::parse_prefix("http://h/dir/").is_err());
        Ok(())
    }
}
