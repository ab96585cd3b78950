//! Fetching one remote object whole into memory: the byte cap checked against the object's
//! size before the body is read and again as it streams, the body counted against that size
//! (a short one is truncated), and its sha256 checked when one is expected. The buffer is
//! allocated once, at the announced size (up to 256 MiB before any byte arrived): the mesh
//! readers need the whole file in memory anyway, so a temporary file would add a copy and no
//! saving. Bucket objects (`s3://`, `gs://`, `az://`) come through `object_store`;
//! `http(s)://` objects through `http`, which also reads bodies of no announced
//! length and decodes gzip.

use crate::error::{FetchError, FetchErrorKind};
use crate::fetched::{too_large, Fetched, PREALLOCATE_AT_MOST};
use crate::limits::FetchLimits;
use crate::location::RemoteUrl;
use crate::store::Stores;
use futures_util::StreamExt;
use object_store::path::Path as ObjectPath;
use object_store::{GetOptions, ObjectStore};
use sha2::{Digest, Sha256};

/// Fetches remote objects: a small async runtime of its own and the clients made so far.
/// Its methods block; any thread may call them.
#[derive(Debug)]
pub struct Fetcher {
    runtime: tokio::runtime::Runtime,
    stores: Stores,
    http: reqwest::Client,
    limits: FetchLimits,
}

impl Fetcher {
    /// A fetcher with `limits` (one I/O thread; clients are made on first use).
    pub fn new(limits: FetchLimits) -> Result<Self, FetchError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("sparc3d-fetch")
            .enable_all()
            .build()
            .map_err(|e| {
                FetchError::new(
                    "",
                    FetchErrorKind::Other,
                    format!("cannot start the fetch runtime: {e}"),
                )
            })?;
        let stores = Stores::new(limits);
        // After `Stores::new`, which installs the TLS provider reqwest's client needs.
        let http = crate::http::client(&limits)?;
        Ok(Self {
            runtime,
            stores,
            http,
            limits,
        })
    }

    /// The limits every fetch has.
    pub fn limits(&self) -> &FetchLimits {
        &self.limits
    }

    /// The object at `url`, whole; with `expected_sha256`, bytes of another sha256 are a
    /// [`FetchErrorKind::Checksum`] error naming both.
    pub fn fetch(
        &self,
        url: &RemoteUrl,
        expected_sha256: Option<&str>,
    ) -> Result<Fetched, FetchError> {
        let fetched = if url.scheme.is_bucket() {
            let store = self.stores.get(url)?;
            self.runtime
                .block_on(get(&*store, url, self.limits.max_bytes))?
        } else {
            self.runtime
                .block_on(crate::http::get(&self.http, url, &self.limits))?
        };
        match expected_sha256 {
            Some(want) if !want.eq_ignore_ascii_case(&fetched.sha256) => Err(FetchError::new(
                url.to_string(),
                FetchErrorKind::Checksum,
                format!(
                    "the fetched bytes' sha256 is {}, not {want} as the manifest gives it (the \
                     object changed, or the download was damaged)",
                    fetched.sha256
                ),
            )),
            _ => Ok(fetched),
        }
    }

    /// Runs `f` on the fetcher's runtime (for listings).
    pub(crate) fn block_on<F: std::future::Future>(&self, f: F) -> F::Output {
        self.runtime.block_on(f)
    }

    /// The client for `url`'s bucket.
    pub(crate) fn store(
        &self,
        url: &RemoteUrl,
    ) -> Result<std::sync::Arc<dyn ObjectStore>, FetchError> {
        self.stores.get(url)
    }
}

/// The process's one fetcher, made on first use with [`FetchLimits::from_env`] (a byte cap of
/// 4 GiB, the largest mesh file read from disk, unless `SPARC3D_FETCH_MAX_BYTES` says
/// otherwise): clients and their connections are kept across items.
pub fn shared() -> Result<&'static Fetcher, FetchError> {
    static FETCHER: std::sync::OnceLock<Result<Fetcher, FetchError>> = std::sync::OnceLock::new();
    FETCHER
        .get_or_init(|| {
            let limits = FetchLimits::from_env(4 << 30)
                .map_err(|m| FetchError::new("", FetchErrorKind::Other, m))?;
            Fetcher::new(limits)
        })
        .as_ref()
        .map_err(Clone::clone)
}

/// The object store path of `url`'s key.
pub(crate) fn object_path(url: &RemoteUrl) -> ObjectPath {
    ObjectPath::from_iter(url.key().split('/').filter(|p| !p.is_empty()))
}

async fn get(store: &dyn ObjectStore, url: &RemoteUrl, cap: u64) -> Result<Fetched, FetchError> {
    let name = url.to_string();
    let result = store
        .get_opts(&object_path(url), GetOptions::default())
        .await
        .map_err(|e| FetchError::from_store(&name, &e))?;
    let size = result.meta.size;
    if size > cap {
        return Err(too_large(url, size.to_string(), cap));
    }
    // Allocated at the announced size, up to a bound: a server that announces gigabytes and
    // sends little costs no more than what it sends.
    let mut bytes = Vec::with_capacity(size.min(PREALLOCATE_AT_MOST) as usize);
    let mut hasher = Sha256::new();
    let mut body = result.into_stream();
    while let Some(chunk) = body.next().await {
        let chunk = chunk.map_err(|e| {
            let mut err = FetchError::from_store(&name, &e);
            if err.kind == FetchErrorKind::Other {
                err.kind = FetchErrorKind::Truncated;
            }
            err.message = format!(
                "the body broke off after {} of {size} bytes: {}",
                bytes.len(),
                err.message
            );
            err
        })?;
        if (bytes.len() + chunk.len()) as u64 > cap {
            return Err(too_large(url, format!("more than {cap}"), cap));
        }
        hasher.update(&chunk);
        bytes.extend_from_slice(&chunk);
    }
    if bytes.len() as u64 != size {
        return Err(FetchError::new(
            name,
            FetchErrorKind::Truncated,
            format!(
                "the body has {} bytes, the server announced {size} (truncated)",
                bytes.len()
            ),
        ));
    }
    // sha2's own lower-case hex (two digits a byte), as `sparc3d_schema::hex` writes every
    // other digest; this crate sits below the schema and does not depend on it.
    let sha256 = format!("{:x}", hasher.finalize());
    Ok(Fetched { bytes, sha256 })
}
