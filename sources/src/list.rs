//! Listing a bucket prefix whole: every object under it with its size and ETag, sorted by
//! key, or an error; never a part of a listing that failed halfway.

use crate::error::{FetchError, FetchErrorKind};
use crate::fetch::Fetcher;
use crate::location::RemoteUrl;
use futures_util::StreamExt;
use object_store::path::Path as ObjectPath;

/// One object of a listing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listed {
    /// Its URL.
    pub url: RemoteUrl,
    /// Its size in bytes.
    pub size: u64,
    /// Its ETag, when the store gives one (quotes removed).
    pub etag: Option<String>,
}

impl Fetcher {
    /// Every object under `prefix` (a folder-like prefix: `s3://bucket/meshes/` lists
    /// `meshes/...`), sorted by key. A failure at any page is an error naming the prefix and
    /// how many objects had been listed, and nothing is returned.
    pub fn list(&self, prefix: &RemoteUrl) -> Result<Vec<Listed>, FetchError> {
        let store = self.store(prefix)?;
        self.list_in(&*store, prefix)
    }

    /// [`Fetcher::list`] in `store`.
    pub(crate) fn list_in(
        &self,
        store: &dyn object_store::ObjectStore,
        prefix: &RemoteUrl,
    ) -> Result<Vec<Listed>, FetchError> {
        let key = prefix.key();
        let path = ObjectPath::from_iter(key.split('/').filter(|p| !p.is_empty()));
        let name = prefix.to_string();
        let mut out = self.block_on(collect(store.list(Some(&path)), &name, prefix))?;
        out.sort_by_key(|l| l.url.key());
        if out.is_empty() {
            return Err(FetchError::new(
                name,
                FetchErrorKind::NotFound,
                "no object under this prefix",
            ));
        }
        Ok(out)
    }
}

/// Every object of a listing's `stream`, their URLs made from `root`'s bucket; a failure at any
/// page is an error naming `name` and how many objects had been listed.
pub(crate) async fn collect(
    mut stream: futures_util::stream::BoxStream<'_, object_store::Result<object_store::ObjectMeta>>,
    name: &str,
    root: &RemoteUrl,
) -> Result<Vec<Listed>, FetchError> {
    let mut out = Vec::new();
    while let Some(meta) = stream.next().await {
        let meta = meta.map_err(|e| {
            let mut err = FetchError::from_store(name, &e);
            err.message = format!(
                "the listing failed after {} objects: {}",
                out.len(),
                err.message
            );
            err
        })?;
        out.push(Listed {
            url: root.with_key(meta.location.as_ref()),
            size: meta.size,
            etag: meta.e_tag.as_deref().map(bare_etag),
        });
    }
    Ok(out)
}

/// An ETag as listings give it: without its quotes (a GET or HEAD keeps them).
pub fn bare_etag(etag: &str) -> String {
    etag.trim_matches('"').to_string()
}
