//! The meshes under a bucket prefix (`s3://bucket/prefix/`, `gs://`, `az://`), as
//! [`crate::folder_scan`] finds those below a folder: the prefix listed whole (a listing that
//! fails at any page is an error, and nothing is returned), objects with a mesh extension kept
//! in key order, each identified as [`IdFrom`] says, identical duplicates dropped.

use crate::folder_scan::Collected;
use crate::record::ManifestRecord;
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use sparc3d_sources::list::Listed;
use sparc3d_sources::RemoteUrl;
use std::collections::HashMap;
use std::path::Path;

/// How the objects of a listing get their ids.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdFrom {
    /// The sha256 of the bytes, as for files on disk: every object is downloaded and hashed
    /// (the whole prefix crosses the network once), ids are the content's, identical
    /// objects are found, and workers check the bytes they fetch against it.
    Sha256,
    /// The store's ETag: no download. An ETag is the MD5 of a single-part upload but not
    /// of a multipart one, differs between stores, and is not checked by the worker (rows
    /// record the sha256 of what was converted).
    Etag,
    /// The object key: no download; the id names the object, not its content, so a
    /// changed object keeps its id and a copy under another key is a second item.
    Key,
}

/// An object's id and, when its bytes were hashed, their sha256.
type Identity = (String, Option<String>);

/// The mesh objects under `prefix`, identified by `id_from`; objects that could not be
/// fetched for hashing are printed and counted (as unreadable files are in a folder scan).
pub fn collect(prefix: &str, id_from: IdFrom) -> Result<Collected> {
    let prefix = RemoteUrl::parse_prefix(prefix)?;
    let fetcher = sparc3d_sources::shared()?;
    let listed = fetcher
        .list(&prefix)
        .with_context(|| format!("listing {prefix}; nothing was written"))?;
    let meshes: Vec<Listed> = listed
        .into_iter()
        .filter(|l| sparcubes::io::Format::from_extension(Path::new(&l.url.key())).is_some())
        .collect();
    if meshes.is_empty() {
        bail!("{prefix}: no mesh object under this prefix (.obj, .ply, .stl, .off, .gltf, .glb)");
    }
    let identified: Vec<(Listed, Result<Identity>)> = match id_from {
        IdFrom::Sha256 => meshes
            .into_par_iter()
            .map(|l| {
                let sha = fetcher.fetch(&l.url, None).map(|f| f.sha256);
                let id = sha
                    .map(|s| (s.clone(), Some(s)))
                    .map_err(anyhow::Error::from);
                (l, id)
            })
            .collect(),
        IdFrom::Etag => meshes
            .into_iter()
            .map(|l| {
                let id = match &l.etag {
                    Some(tag) if !tag.is_empty() => Ok((tag.clone(), None)),
                    _ => Err(anyhow::anyhow!("{}: the store gives no ETag", l.url)),
                };
                (l, id)
            })
            .collect(),
        IdFrom::Key => meshes
            .into_iter()
            .map(|l| {
                let key = l.url.key();
                (l, Ok((key, None)))
            })
            .collect(),
    };
    let mut out = Collected {
        records: Vec::new(),
        duplicates: 0,
        unreadable: 0,
        skipped: 0,
    };
    let mut seen: HashMap<String, String> = HashMap::new();
    for (listed, id) in identified {
        let uri = listed.url.to_string();
        let (id, sha256) = match id {
            Ok(v) => v,
            Err(e) => {
                eprintln!("skipping unreadable object: {e:#}");
                out.unreadable += 1;
                continue;
            }
        };
        if let Some(first) = seen.get(&id) {
            eprintln!("duplicate: {uri} is identical to {first}");
            out.duplicates += 1;
            continue;
        }
        seen.insert(id.clone(), uri.clone());
        out.records.push(ManifestRecord {
            id,
            format: Path::new(&listed.url.key())
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase()),
            uri,
            sha256,
            extra: Default::default(),
        });
    }
    Ok(out)
}
