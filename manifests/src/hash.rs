//! The sha256 that identifies a mesh file: a manifest row without id or sha256 is identified by
//! it (a remote one is fetched to be hashed), and `manifest build` writes it for every file it
//! finds.

use sha2::{Digest, Sha256};
use sparc3d_schema::hex::hex;
use std::path::{Path, PathBuf};

/// A file that could not be hashed: what was being done, the file, and the I/O error.
#[derive(Debug)]
pub struct HashError {
    /// `opening` or `reading`.
    pub stage: &'static str,
    /// The file.
    pub path: PathBuf,
    /// The underlying error.
    pub source: std::io::Error,
}

impl std::fmt::Display for HashError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}: {}", self.stage, self.path.display(), self.source)
    }
}

impl std::error::Error for HashError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// Hex sha256 of a regular file's bytes. A FIFO, device or socket (also behind a link) is
/// refused at once ([`sparcubes::io::open_regular`]) instead of being read forever.
pub fn file_sha256(path: &Path) -> Result<String, HashError> {
    let fail = |stage, source| HashError {
        stage,
        path: path.to_path_buf(),
        source,
    };
    let (mut f, _) = sparcubes::io::open_regular(path).map_err(|e| fail("opening", e))?;
    let mut h = Sha256::new();
    std::io::copy(&mut f, &mut h).map_err(|e| fail("reading", e))?;
    Ok(hex(&h.finalize()))
}

/// Hex sha256 of a manifest row's source: a local file ([`file_sha256`]) or a remote object,
/// fetched whole to be hashed ([`sparc3d_sources::shared`]'s limits and retries).
pub fn source_sha256(uri: &str) -> anyhow::Result<String> {
    match sparc3d_sources::Location::parse(uri)? {
        sparc3d_sources::Location::Local(path) => Ok(file_sha256(&path)?),
        sparc3d_sources::Location::Remote(url) => {
            Ok(sparc3d_sources::shared()?.fetch(&url, None)?.sha256)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_hashes_to_the_sha256_of_its_bytes() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let path = dir.path().join("a.obj");
        std::fs::write(&path, b"abc")?;
        let abc = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
        assert_eq!(file_sha256(&path)?, abc);
        let missing = file_sha256(&dir.path().join("missing.obj"))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(missing.starts_with("opening "), "{missing}");
        Ok(())
    }
}
