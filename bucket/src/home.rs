//! Where a job lives: a folder, or a prefix of a bucket.

use anyhow::Result;
use sparc3d_sources::RemoteUrl;
use std::path::{Path, PathBuf};

/// A job's home, as a command's JOB argument names it.
#[derive(Debug, Clone, PartialEq)]
pub enum JobHome {
    /// A job folder (a local path; shared filesystems included).
    Folder(PathBuf),
    /// A bucket prefix: `s3://bucket/jobs/name`, `gs://…`, `az://…`.
    Bucket(RemoteUrl),
}

impl JobHome {
    /// The home named by `arg`: a bucket URL, or else a folder. `http(s)://` and other URLs
    /// that cannot hold a job are refused, naming the schemes that can.
    pub fn parse(arg: &Path) -> Result<Self> {
        let text = arg.to_string_lossy();
        if !sparc3d_sources::location::is_url(&text) || text.starts_with("file://") {
            let path = text.strip_prefix("file://").map(PathBuf::from);
            return Ok(Self::Folder(path.unwrap_or_else(|| arg.to_path_buf())));
        }
        match RemoteUrl::parse_prefix(&text) {
            Ok(url) => Ok(Self::Bucket(url)),
            Err(e) => anyhow::bail!(
                "{e}: a job's home is a folder or a bucket prefix (s3://, gs://, az://)"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_and_bucket_prefixes_are_told_apart() -> Result<()> {
        assert_eq!(
            JobHome::parse(Path::new("jobs/a"))?,
            JobHome::Folder("jobs/a".into())
        );
        assert!(matches!(
            JobHome::parse(Path::new("s3://bkt/jobs/a"))?,
            JobHome::Bucket(u) if u.bucket() == "bkt" && u.key().trim_end_matches('/') == "jobs/a"
        ));
        assert!(JobHome::parse(Path::new("https://example.com/job")).is_err());
        Ok(())
    }
}
