//! An item's bytes, from where its `uri` says: a local file read as `sparcubes::io` reads
//! one, or a remote object fetched whole (`sparc3d-sources`) with the process's one
//! [`Fetcher`], made on first use with the limits of the environment
//! (`SPARC3D_FETCH_*`). A glTF file fetched from a URL reads its external buffers from the
//! same prefix ([`RemoteBuffers`]).

use sparc3d_schema::{ErrorClass, FrozenItem};
use sparc3d_sources::{FetchError, FetchErrorKind, Fetcher, Location, RemoteUrl};
use std::cell::RefCell;
use std::path::PathBuf;

/// The bytes of an item's source and what locates the rest of it.
#[derive(Debug)]
pub struct SourceBytes {
    /// The bytes.
    pub bytes: Vec<u8>,
    /// Their sha256, when taken while fetching (a local file is hashed by the caller).
    pub sha256: Option<String>,
    /// The path that names the source in messages and gives its extension: the file, or the
    /// URL as a path.
    pub path: PathBuf,
    /// The remote object, when fetched.
    pub remote: Option<RemoteUrl>,
}

/// Why an item's source could not be read: the class its failed row records and the message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceError {
    /// `fetch` for remote sources (`too_large` over the byte cap), else the load error's.
    pub class: ErrorClass,
    /// What happened, naming the source.
    pub message: String,
}

impl From<FetchError> for SourceError {
    fn from(e: FetchError) -> Self {
        let class = match e.kind {
            FetchErrorKind::TooLarge => ErrorClass::Geometry(sparcubes::ErrorClass::TooLarge),
            _ => ErrorClass::Fetch,
        };
        Self {
            class,
            message: e.to_string(),
        }
    }
}

/// The process's fetcher ([`sparc3d_sources::shared`]).
pub fn fetcher() -> Result<&'static Fetcher, FetchError> {
    sparc3d_sources::shared()
}

/// Reads `item`'s source. A remote one is checked against the item's frozen sha256 while
/// it is fetched (a mismatch is a `fetch` failure naming both hashes).
pub fn read(item: &FrozenItem) -> Result<SourceBytes, SourceError> {
    let uri = &item.record.uri;
    match Location::parse(uri) {
        Err(e) => Err(SourceError {
            class: ErrorClass::Fetch,
            message: e.to_string(),
        }),
        Ok(Location::Local(path)) => match sparcubes::io::read_source(&path) {
            Ok(bytes) => Ok(SourceBytes {
                bytes,
                sha256: None,
                path,
                remote: None,
            }),
            Err(e) => Err(SourceError {
                class: e.class().into(),
                message: e.to_string(),
            }),
        },
        Ok(Location::Remote(url)) => {
            let fetched = fetcher()?.fetch(&url, item.record.sha256.as_deref())?;
            Ok(SourceBytes {
                bytes: fetched.bytes,
                sha256: Some(fetched.sha256),
                path: PathBuf::from(url.to_string()),
                remote: Some(url),
            })
        }
    }
}

/// Loads the mesh that `uri` names again after its item was converted, for the commands that
/// compare an item with its source (`validate`, `eval`, `report`'s pictures): a local file as
/// [`sparcubes::io::load`] reads it, a remote one fetched (its frozen sha256 is not asked
/// for: the stored row already records what was converted) with a glTF file's buffers from
/// beside it. The error names the source.
pub fn load_mesh(uri: &str) -> Result<sparcubes::io::LoadedMesh, String> {
    match Location::parse(uri).map_err(|e| e.to_string())? {
        Location::Local(path) => sparcubes::io::load(&path).map_err(|e| e.to_string()),
        Location::Remote(url) => {
            let fetched = fetcher()
                .and_then(|f| f.fetch(&url, None))
                .map_err(|e| e.to_string())?;
            let buffers = RemoteBuffers::new(url.clone());
            let read = |relative: &str| buffers.read(relative);
            let path = PathBuf::from(url.to_string());
            sparcubes::io::load_read_with(
                &fetched.bytes,
                &path,
                sparcubes::io::Buffers::Relative(&read),
            )
            .map_err(|e| e.to_string())
        }
    }
}

/// Reads a remote glTF file's external buffers from its own prefix, keeping the first fetch
/// error so that a load that failed for it is a `fetch` failure, not a parse error.
#[derive(Debug)]
pub struct RemoteBuffers {
    url: RemoteUrl,
    failed: RefCell<Option<FetchError>>,
}

impl RemoteBuffers {
    /// Buffers next to `url`.
    pub fn new(url: RemoteUrl) -> Self {
        Self {
            url,
            failed: RefCell::new(None),
        }
    }

    /// The buffer at `relative` (checked by the glTF reader: plain components only).
    pub fn read(&self, relative: &str) -> Result<Vec<u8>, String> {
        let result = fetcher().and_then(|f| f.fetch(&self.url.sibling(relative), None));
        result.map(|f| f.bytes).map_err(|e| {
            let text = e.to_string();
            self.failed.borrow_mut().get_or_insert(e);
            text
        })
    }

    /// The first buffer fetch that failed, if any.
    pub fn failure(&self) -> Option<FetchError> {
        self.failed.borrow().clone()
    }
}
