//! Making a job's home a bucket: `init` freezes the manifest into a local folder as for any
//! job, then the two files go up, `manifest.jsonl` first and `job.json` last (created only if
//! absent): a job exists in a bucket once its `job.json` does, and then with its manifest.

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
    if let Some(there) = prefix.get(keys::JOB_FILE)? {
        if there.bytes == job_file {
            return Ok(());
        }
        bail!(
            "{}: a job with another config or manifest is there already; a job never changes \
             once made (use another prefix)",
            prefix.root()
        );
    }
    prefix
        .put(keys::MANIFEST, read(keys::MANIFEST)?, WriteMode::Overwrite)
        .with_context(|| format!("uploading {}", prefix.url(keys::MANIFEST)))?;
    match prefix
        .put(keys::JOB_FILE, job_file, WriteMode::Create)
        .with_context(|| format!("uploading {}", prefix.url(keys::JOB_FILE)))?
    {
        Written::Done(_) => Ok(()),
        Written::Refused => bail!(
            "{}: another `init` made a job there at the same moment",
            prefix.root()
        ),
    }
}
