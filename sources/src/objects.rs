//! The objects under one bucket prefix, read and written as a job whose home is a bucket
//! needs them: whole small objects with their ETags, conditional writes (create only if
//! absent, replace only if unchanged: how S3, GCS and Azure each let two writers race for a
//! name and exactly one win), files streamed up and down (multipart above
//! [`SINGLE_PUT_MAX`]), listings and deletes. Every call blocks on the [`Fetcher`]'s runtime
//! and has its clients' time-outs and retries (throttling and server errors are retried with
//! backoff by the client).

use crate::error::{FetchError, FetchErrorKind};
use crate::fetch::Fetcher;
pub use crate::list::bare_etag;
use crate::list::Listed;
use crate::location::RemoteUrl;
use futures_util::StreamExt;
use object_store::path::Path as ObjectPath;
use object_store::{
    ObjectStore, ObjectStoreExt, PutMode, PutOptions, PutPayload, UpdateVersion, WriteMultipart,
};
use sha2::{Digest, Sha256};
use std::io::{Read, Write};
use std::path::Path;
use std::sync::Arc;

/// Files up to this size are uploaded in one request; larger ones in parts of this size.
pub const SINGLE_PUT_MAX: u64 = 32 << 20;

/// Parts of a multipart upload in flight at once.
const PARTS_IN_FLIGHT: usize = 4;

/// How a [`Prefix::put`] may treat an object already at the key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WriteMode {
    /// Replace whatever is there.
    Overwrite,
    /// Write only if no object is there.
    Create,
    /// Write only if the object there is still this version.
    Replace(Version),
}

/// Which version of an object a conditional write replaces: its ETag (S3, Azure) and its
/// version (a GCS generation), as the store gave them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Version {
    /// The ETag (quotes kept).
    pub etag: Option<String>,
    /// The store's version of the object, when it has one.
    pub version: Option<String>,
}

/// How a conditional write ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Written {
    /// Written; the new object's version.
    Done(Version),
    /// Not written: an object was there ([`WriteMode::Create`]) or it had changed
    /// ([`WriteMode::Replace`]).
    Refused,
}

/// A small object read whole.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    /// Its bytes.
    pub bytes: Vec<u8>,
    /// Its version, for a conditional write that replaces it.
    pub version: Version,
}

/// A file streamed down: its size and sha256.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Downloaded {
    /// Bytes written to the file.
    pub bytes: u64,
    /// Their sha256 (lower-case hex).
    pub sha256: String,
    /// The ETag of the object read (quotes removed, as in a listing), when the store gives
    /// one.
    pub etag: Option<String>,
}

/// The objects under one prefix of a bucket (`s3://bucket/jobs/a` holds `jobs/a/...`); keys
/// given to its methods are relative to it.
#[derive(Debug, Clone)]
pub struct Prefix<'f> {
    fetcher: &'f Fetcher,
    root: RemoteUrl,
    store: Arc<dyn ObjectStore>,
}

impl Fetcher {
    /// The objects under `root` (a bucket URL; its client is made now, so missing or
    /// malformed settings are reported here).
    pub fn prefix(&self, root: &RemoteUrl) -> Result<Prefix<'_>, FetchError> {
        Ok(Prefix {
            fetcher: self,
            root: root.clone(),
            store: self.store(root)?,
        })
    }
}

impl<'f> Prefix<'f> {
    /// The objects under `root` in `store` rather than in the client made for `root`'s
    /// scheme (an in-memory store in tests, a store configured by the caller).
    pub fn with_store(fetcher: &'f Fetcher, root: &RemoteUrl, store: Arc<dyn ObjectStore>) -> Self {
        Self {
            fetcher,
            root: root.clone(),
            store,
        }
    }

    /// The prefix's own URL.
    pub fn root(&self) -> &RemoteUrl {
        &self.root
    }

    /// The URL of the object at `key`.
    pub fn url(&self, key: &str) -> RemoteUrl {
        let base = self.root.key();
        let base = base.trim_end_matches('/');
        if base.is_empty() {
            self.root.with_key(key)
        } else {
            self.root.with_key(&format!("{base}/{key}"))
        }
    }

    fn path(&self, key: &str) -> ObjectPath {
        crate::fetch::object_path(&self.url(key))
    }

    fn error(&self, key: &str, e: &object_store::Error) -> FetchError {
        FetchError::from_store(&self.url(key).to_string(), e)
    }

    /// The store's answer to a read of the object at `key` (its body not read yet); `None`
    /// when there is no object.
    async fn open(&self, key: &str) -> Result<Option<object_store::GetResult>, FetchError> {
        match self.store.get(&self.path(key)).await {
            Ok(r) => Ok(Some(r)),
            Err(object_store::Error::NotFound { .. }) => Ok(None),
            Err(e) => Err(self.error(key, &e)),
        }
    }

    /// The object at `key` read whole with its ETag; `None` when there is none.
    pub fn get(&self, key: &str) -> Result<Option<Object>, FetchError> {
        self.fetcher.block_on(async {
            let Some(result) = self.open(key).await? else {
                return Ok(None);
            };
            let version = Version {
                etag: result.meta.e_tag.clone(),
                version: result.meta.version.clone(),
            };
            let bytes = result.bytes().await.map_err(|e| self.error(key, &e))?;
            Ok(Some(Object {
                bytes: bytes.to_vec(),
                version,
            }))
        })
    }

    /// Whether an object is at `key`, with its size.
    pub fn size(&self, key: &str) -> Result<Option<u64>, FetchError> {
        Ok(self.head(key)?.map(|l| l.size))
    }

    /// The object at `key` as a listing shows it (size and ETag, read with one HEAD
    /// request), or `None` when there is none.
    pub fn head(&self, key: &str) -> Result<Option<Listed>, FetchError> {
        let path = self.path(key);
        self.fetcher
            .block_on(async {
                match self.store.head(&path).await {
                    Ok(meta) => Ok(Some(Listed {
                        url: self.url(key),
                        size: meta.size,
                        etag: meta.e_tag.as_deref().map(bare_etag),
                    })),
                    Err(object_store::Error::NotFound { .. }) => Ok(None),
                    Err(e) => Err(e),
                }
            })
            .map_err(|e| self.error(key, &e))
    }

    /// Writes `bytes` at `key` as `mode` allows.
    pub fn put(&self, key: &str, bytes: Vec<u8>, mode: WriteMode) -> Result<Written, FetchError> {
        let path = self.path(key);
        let mode = match mode {
            WriteMode::Overwrite => PutMode::Overwrite,
            WriteMode::Create => PutMode::Create,
            WriteMode::Replace(v) => PutMode::Update(UpdateVersion {
                e_tag: v.etag,
                version: v.version,
            }),
        };
        let options = PutOptions {
            mode,
            ..PutOptions::default()
        };
        let result =
            self.fetcher
                .block_on(self.store.put_opts(&path, PutPayload::from(bytes), options));
        match result {
            Ok(r) => Ok(Written::Done(Version {
                etag: r.e_tag,
                version: r.version,
            })),
            Err(object_store::Error::AlreadyExists { .. })
            | Err(object_store::Error::Precondition { .. }) => Ok(Written::Refused),
            Err(e) => Err(self.error(key, &e)),
        }
    }

    /// Uploads the file at `file` to `key` (replacing what is there), streamed in parts when
    /// it is larger than [`SINGLE_PUT_MAX`]; a failed upload leaves no object at `key`.
    pub fn upload(&self, key: &str, file: &Path) -> Result<(), FetchError> {
        let local = |e: std::io::Error| {
            FetchError::new(
                self.url(key).to_string(),
                FetchErrorKind::Other,
                format!("reading {} to upload it: {e}", file.display()),
            )
        };
        let size = std::fs::metadata(file).map_err(local)?.len();
        if size <= SINGLE_PUT_MAX {
            let bytes = std::fs::read(file).map_err(local)?;
            return self.put(key, bytes, WriteMode::Overwrite).map(|_| ());
        }
        let path = self.path(key);
        let mut reader = std::fs::File::open(file).map_err(local)?;
        self.fetcher.block_on(async {
            let upload = self
                .store
                .put_multipart(&path)
                .await
                .map_err(|e| self.error(key, &e))?;
            let mut parts = WriteMultipart::new_with_chunk_size(upload, SINGLE_PUT_MAX as usize);
            let mut buf = vec![0u8; 1 << 20];
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => n,
                    Err(e) => {
                        let _ = parts.abort().await;
                        return Err(local(e));
                    }
                };
                if let Err(e) = parts.wait_for_capacity(PARTS_IN_FLIGHT).await {
                    return Err(self.error(key, &e));
                }
                parts.write(&buf[..n]);
            }
            parts.finish().await.map_err(|e| self.error(key, &e))?;
            Ok(())
        })
    }

    /// Streams the object at `key` into a new file at `file`, hashing it on the way; a body
    /// that breaks off is an error (the file is then removed), and so is no object.
    pub fn download(&self, key: &str, file: &Path) -> Result<Downloaded, FetchError> {
        let local = |e: std::io::Error| {
            FetchError::new(
                self.url(key).to_string(),
                FetchErrorKind::Other,
                format!("writing {}: {e}", file.display()),
            )
        };
        let mut out = std::io::BufWriter::new(std::fs::File::create(file).map_err(local)?);
        let result = match self.stream(key, &mut out) {
            Ok(Some(got)) => out.flush().map(|()| got).map_err(local),
            Ok(None) => Err(FetchError::new(
                self.url(key).to_string(),
                FetchErrorKind::NotFound,
                "no object there",
            )),
            Err(e) => Err(e),
        };
        if result.is_err() {
            let _ = std::fs::remove_file(file);
        }
        result
    }

    /// Reads the object at `key` whole and hashes it without keeping its bytes (what holds
    /// it, checked, not copied); `None` when there is no object.
    pub fn hash(&self, key: &str) -> Result<Option<Downloaded>, FetchError> {
        self.stream(key, &mut std::io::sink())
    }

    /// Streams the object at `key` into `out`, hashing it on the way; `None` when there is
    /// no object. A body that breaks off or is shorter than announced is an error.
    fn stream(&self, key: &str, out: &mut dyn Write) -> Result<Option<Downloaded>, FetchError> {
        self.fetcher.block_on(async {
            let Some(result) = self.open(key).await? else {
                return Ok(None);
            };
            let size = result.meta.size;
            let etag = result.meta.e_tag.as_deref().map(bare_etag);
            let mut hasher = Sha256::new();
            let mut written = 0u64;
            let mut body = result.into_stream();
            while let Some(chunk) = body.next().await {
                let chunk = chunk.map_err(|e| {
                    let mut err = self.error(key, &e);
                    err.kind = FetchErrorKind::Truncated;
                    err.message = format!("the body broke off after {written} of {size} bytes");
                    err
                })?;
                hasher.update(&chunk);
                out.write_all(&chunk).map_err(|e| {
                    FetchError::new(
                        self.url(key).to_string(),
                        FetchErrorKind::Other,
                        e.to_string(),
                    )
                })?;
                written += chunk.len() as u64;
            }
            if written != size {
                return Err(FetchError::new(
                    self.url(key).to_string(),
                    FetchErrorKind::Truncated,
                    format!("the body has {written} bytes, the store announced {size}"),
                ));
            }
            Ok(Some(Downloaded {
                bytes: written,
                sha256: format!("{:x}", hasher.finalize()),
                etag,
            }))
        })
    }

    /// Every object whose key starts with `key_prefix` (relative to this prefix), sorted by
    /// key; none is an empty list, not an error.
    pub fn list(&self, key_prefix: &str) -> Result<Vec<Listed>, FetchError> {
        match self.fetcher.list_in(&*self.store, &self.url(key_prefix)) {
            Ok(found) => Ok(found),
            Err(e) if e.kind == FetchErrorKind::NotFound => Ok(Vec::new()),
            Err(e) => Err(e),
        }
    }

    /// The objects whose key starts with `key_prefix` (relative to this prefix; a name prefix
    /// such as `shards/part-00003.`, not only a folder), sorted by key. The store lists from
    /// that name on (S3's start-after) and the listing stops at the first key past them, so
    /// the cost follows what matches, not the size of the folder.
    pub fn list_starting(&self, key_prefix: &str) -> Result<Vec<Listed>, FetchError> {
        let full = self.url(key_prefix).key();
        let dir = full.rsplit_once('/').map_or("", |(d, _)| d);
        let folder = ObjectPath::from_iter(dir.split('/').filter(|p| !p.is_empty()));
        let offset = ObjectPath::from_iter(full.split('/').filter(|p| !p.is_empty()));
        self.fetcher.block_on(async {
            let mut stream = self.store.list_with_offset(Some(&folder), &offset);
            let mut out = Vec::new();
            while let Some(meta) = stream.next().await {
                let meta = meta.map_err(|e| self.error(key_prefix, &e))?;
                if !meta.location.as_ref().starts_with(full.as_str()) {
                    break;
                }
                out.push(Listed {
                    url: self.root.with_key(meta.location.as_ref()),
                    size: meta.size,
                    etag: meta.e_tag.as_deref().map(bare_etag),
                });
            }
            Ok(out)
        })
    }

    /// Every object of this prefix whose key sorts after `key` (relative to this prefix), in
    /// one listing that starts there (S3's start-after): the keys before it are not listed,
    /// so a job's `shards/` and `state/` are read without its `manifest/`. A failure at any
    /// page is an error naming how many objects had been listed; nothing is returned.
    pub fn list_from(&self, key: &str) -> Result<Vec<Listed>, FetchError> {
        let folder = crate::fetch::object_path(&self.root);
        let offset = self.path(key);
        let name = self.url(key).to_string();
        let stream = self.store.list_with_offset(Some(&folder), &offset);
        let mut out = self
            .fetcher
            .block_on(crate::list::collect(stream, &name, &self.root))?;
        out.sort_by_key(|l| l.url.key());
        Ok(out)
    }

    /// The key of `listed` relative to this prefix.
    pub fn relative_key(&self, listed: &Listed) -> String {
        let base = self.root.key();
        let base = base.trim_end_matches('/');
        let key = listed.url.key();
        match key.strip_prefix(base) {
            Some(rest) if !base.is_empty() => rest.trim_start_matches('/').to_string(),
            _ => key,
        }
    }

    /// Copies the object at `from` to `to` (replacing what is there), within the store.
    pub fn copy(&self, from: &str, to: &str) -> Result<(), FetchError> {
        let (a, b) = (self.path(from), self.path(to));
        self.fetcher
            .block_on(self.store.copy(&a, &b))
            .map_err(|e| self.error(from, &e))
    }

    /// Deletes the object at `key`; one that is not there is no error.
    pub fn delete(&self, key: &str) -> Result<(), FetchError> {
        let path = self.path(key);
        match self.fetcher.block_on(self.store.delete(&path)) {
            Ok(()) | Err(object_store::Error::NotFound { .. }) => Ok(()),
            Err(e) => Err(self.error(key, &e)),
        }
    }
}
