//! Making a job's home a bucket: `init` freezes the manifest into a local folder as for any
//! job, then its files go up, each created only if absent: the frozen manifest's slices and
//! index pages first (named by their content, so two `init`s never write one name with two
//! contents), then `job.json`, which pins the pages. A job exists in a bucket once its
//! `job.json` does, and then with its manifest.
//!
//! Jobs made before slices went up as `manifest.jsonl` and `job.json`, in that order:
//! Of two `init`s at once on one URL with different manifests, exactly one creates
//! `manifest.jsonl`; the other finds another manifest there and stops before its `job.json`,
//! so a job's two files always come from one `init` (with the same manifest and different
//! configs, one `job.json` is created and the other `init` is refused). An `init` stopped
//! between the two uploads leaves a manifest without a job: `init` with the same manifest
//! finishes the job; with another one it is refused, naming the object to delete.

use crate::keys;
use anyhow::{bail, Context, Result};
use sparc3d_sources::objects::{Prefix, WriteMode, Written};
use std::path::Path;

/// Uploads the job files of the local job folder `local` to `prefix`. A job already there
/// with the same `job.json` is left as it is; one with another is refused.
pub fn publish(prefix: &Prefix<'_>, local: &Path) -> Result<()> {
    let read = |name: &str| {
        let path = local.join(name);
        std::fs::read(&path).with_context(|| format!("reading {}", path.display()))
    };
    let job_file = read(keys::JOB_FILE)?;
    if let Some(there) = read_object(prefix, keys::JOB_FILE)? {
        if there == job_file {
            return Ok(());
        }
        bail!(
            "{}: a job with another config or manifest is there already; a job never changes \
             once made (use another prefix)",
            prefix.root()
        );
    }
    let slices = local.join(keys::MANIFEST_FILES);
    if slices.is_dir() {
        upload_slices(prefix, &slices)?;
    } else {
        create(prefix, keys::MANIFEST, read(keys::MANIFEST)?, |_| {
            manifest_taken(prefix)
        })?;
    }
    create(prefix, keys::JOB_FILE, job_file, |_| {
        Err(anyhow::anyhow!(
            "{}: another `init` made a job there at the same moment, with another config or \
             manifest; a job never changes once made (use another prefix)",
            prefix.root()
        ))
    })
}

/// Uploads in which a sliced job's files go up at once.
const UPLOADS_IN_FLIGHT: usize = 8;

/// Uploads every file of the local `manifest/` folder `dir` (the frozen manifest's slices and
/// index pages), each created only if absent, a few at once. Their names carry their content's
/// sha256, so an object already there under a name is the same file (another `init` of the
/// same rows); one with other bytes is refused, naming it.
fn upload_slices(prefix: &Prefix<'_>, dir: &Path) -> Result<()> {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))? {
        let entry = entry.with_context(|| format!("listing {}", dir.display()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if !name.starts_with('.') && !name.contains(".tmp-") {
            names.push(name);
        }
    }
    names.sort();
    crate::parallel::each(&names, UPLOADS_IN_FLIGHT, |name| {
        let path = dir.join(name);
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        let key = keys::manifest_file(name);
        create(prefix, &key, bytes, |_| {
            Err(anyhow::anyhow!(
                "{}: another object is there under this name, which a frozen manifest's \
                 file of these bytes alone should have; delete it and run `init` again",
                prefix.url(&key)
            ))
        })
    })?;
    Ok(())
}

/// Creates `key` with `bytes` unless an object is there; one with the same bytes is as good
/// (the same `init` run twice at once), another is `refused`'s error.
fn create(
    prefix: &Prefix<'_>,
    key: &str,
    bytes: Vec<u8>,
    refused: impl FnOnce(&[u8]) -> Result<()>,
) -> Result<()> {
    let written = prefix
        .put(key, bytes.clone(), WriteMode::Create)
        .with_context(|| format!("uploading {}", prefix.url(key)))?;
    if written != Written::Refused {
        return Ok(());
    }
    match read_object(prefix, key)? {
        Some(there) if there == bytes => Ok(()),
        Some(there) => refused(&there),
        None => bail!(
            "{}: refused as existing, then not found (deleted meanwhile?): run `init` again",
            prefix.url(key)
        ),
    }
}

/// The error when another manifest is at the prefix: with a `job.json` now, another `init`
/// made its job; without one, another `init` is making it, or one stopped between its uploads.
fn manifest_taken(prefix: &Prefix<'_>) -> Result<()> {
    if read_object(prefix, keys::JOB_FILE)?.is_some() {
        bail!(
            "{}: another `init` made a job there at the same moment, with another manifest; a \
             job never changes once made (use another prefix)",
            prefix.root()
        );
    }
    bail!(
        "{}: another manifest is there without a job.json: another `init` with another \
         manifest is making a job there now (use another prefix), or one was stopped between \
         its two uploads; if none is running, delete {} and run `init` again",
        prefix.root(),
        prefix.url(keys::MANIFEST)
    )
}

/// The bytes of the object at `key`, if any.
fn read_object(prefix: &Prefix<'_>, key: &str) -> Result<Option<Vec<u8>>> {
    let found = prefix
        .get(key)
        .with_context(|| format!("reading {}", prefix.url(key)))?;
    Ok(found.map(|o| o.bytes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lease::tests::memory_prefix;

    fn job_folder(manifest: &str, job: &str) -> Result<tempfile::TempDir> {
        let dir = tempfile::tempdir()?;
        std::fs::write(dir.path().join(keys::MANIFEST), manifest)?;
        std::fs::write(dir.path().join(keys::JOB_FILE), job)?;
        Ok(dir)
    }

    fn refusal(prefix: &Prefix<'_>, dir: &Path) -> String {
        publish(prefix, dir)
            .err()
            .map(|e| format!("{e:#}"))
            .unwrap_or_default()
    }

    /// Issue 41, defect 3: the manifest of an `init` racing another one with another
    /// manifest was overwritten, leaving `job.json` of one and `manifest.jsonl` of the other.
    /// Here the second `init`'s upload comes between the first's two.
    #[test]
    fn a_second_init_with_another_manifest_never_mixes_its_files_in() -> Result<()> {
        let prefix = memory_prefix();
        let a = job_folder("{\"a\":1}\n", "{\"job\":\"a\"}")?;
        let b = job_folder("{\"b\":1}\n{\"b\":2}\n", "{\"job\":\"b\"}")?;
        // `a` uploaded its manifest and has not created its job.json yet.
        prefix.put(keys::MANIFEST, b"{\"a\":1}\n".to_vec(), WriteMode::Create)?;
        let e = refusal(&prefix, b.path());
        assert!(
            e.contains("another manifest is there without a job.json")
                && e.contains("manifest.jsonl"),
            "{e}"
        );
        publish(&prefix, a.path())?;
        let object = |key: &str| prefix.get(key).ok().flatten().map(|o| o.bytes);
        assert_eq!(object(keys::MANIFEST), Some(b"{\"a\":1}\n".to_vec()));
        assert_eq!(object(keys::JOB_FILE), Some(b"{\"job\":\"a\"}".to_vec()));
        // Afterwards `b` is refused as any other job would be, and nothing changed.
        let e = refusal(&prefix, b.path());
        assert!(e.contains("a job with another config or manifest"), "{e}");
        assert_eq!(object(keys::MANIFEST), Some(b"{\"a\":1}\n".to_vec()));
        // The same `init` again does nothing.
        publish(&prefix, a.path())
    }
}
