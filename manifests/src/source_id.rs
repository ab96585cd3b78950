//! The id of an item made from a local file: the mesh file's sha256 when it names no other
//! file that can be read, else that sha256, `-`, and 16 hex digits of a digest of the files it names (their
//! names and bytes, [`sparcubes::materials::references`]), so that colour variants that share
//! one OBJ (or one `.gltf` with different buffers) are distinct items, and one folder copied
//! whole is still one item. An item's `sha256` stays the mesh file's own: it is what the
//! worker checks the file it reads against.
//!
//! Ids of jobs made before are kept as frozen; only scans and rows without an id made from
//! now on are named this way. Remote sources keep the mesh object's sha256 alone (their
//! siblings are fetched when converted, not when listed).

use crate::hash::{file_sha256, HashError};
use sha2::{Digest, Sha256};
use sparc3d_schema::hex::hex;
use sparcubes::materials::references::named_files;
use std::path::Path;

/// Hex digits of the named files' digest that follow the mesh sha256.
const SUFFIX_DIGITS: usize = 16;

/// The id of the mesh file at `path`, whose bytes hash to `mesh_sha256` (see the module).
/// Only the named files that can be read count (names and bytes): an OBJ whose library is
/// missing is what its readers see, the mesh alone, and keeps the mesh file's sha256.
pub fn source_id(path: &Path, mesh_sha256: &str) -> Result<String, HashError> {
    let named = named_files(path).map_err(|source| HashError {
        stage: "reading the files named by",
        path: path.to_path_buf(),
        source,
    })?;
    let read: Vec<(String, String)> = named
        .into_iter()
        .filter_map(|f| Some((f.name, file_sha256(&f.file.ok()?).ok()?)))
        .collect();
    if read.is_empty() {
        return Ok(mesh_sha256.to_string());
    }
    let mut digest = Sha256::new();
    digest.update(b"sparc3d source id v1\n");
    for (name, sha) in read {
        digest.update(name.as_bytes());
        digest.update(b"\0");
        digest.update(sha.as_bytes());
        digest.update(b"\n");
    }
    let suffix = hex(&digest.finalize());
    Ok(format!("{mesh_sha256}-{}", &suffix[..SUFFIX_DIGITS]))
}

/// Whether `id` is a [`source_id`] made from a mesh file whose sha256 is `sha256` and that
/// names other files (an id of that form only: the export key TRELLIS.2's layout needs,
/// which must tell colour variants apart).
pub fn names_files_of(id: &str, sha256: &str) -> bool {
    id.strip_prefix(sha256)
        .and_then(|rest| rest.strip_prefix('-'))
        .is_some_and(|s| s.len() == SUFFIX_DIGITS && s.bytes().all(|b| b.is_ascii_hexdigit()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two copies of one OBJ with different textures are two ids; the same folder copied is
    /// one; a mesh that names nothing keeps its sha256.
    #[test]
    fn colour_variants_get_their_own_ids() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let folder = |name: &str, texture: &[u8]| -> std::io::Result<std::path::PathBuf> {
            let d = dir.path().join(name);
            std::fs::create_dir(&d)?;
            std::fs::write(d.join("m.obj"), "mtllib m.mtl\nv 0 0 0\n")?;
            std::fs::write(d.join("m.mtl"), "newmtl a\nmap_Kd t.png\n")?;
            std::fs::write(d.join("t.png"), texture)?;
            Ok(d.join("m.obj"))
        };
        let (red, blue, copy) = (
            folder("r", b"red")?,
            folder("b", b"blue")?,
            folder("c", b"red")?,
        );
        let sha = file_sha256(&red)?;
        let ids = [&red, &blue, &copy].map(|p| source_id(p, &sha));
        let [red_id, blue_id, copy_id] = ids;
        let (red_id, blue_id, copy_id) = (red_id?, blue_id?, copy_id?);
        assert_ne!(red_id, blue_id);
        assert_eq!(red_id, copy_id);
        assert!(names_files_of(&red_id, &sha), "{red_id}");
        assert!(!names_files_of(&sha, &sha));
        std::fs::remove_file(dir.path().join("c/t.png"))?;
        assert_ne!(
            source_id(&copy, &sha)?,
            red_id,
            "a missing texture is another item"
        );
        std::fs::remove_file(dir.path().join("c/m.mtl"))?;
        assert_eq!(source_id(&copy, &sha)?, sha, "nothing named can be read");
        let stl = dir.path().join("m.stl");
        std::fs::write(&stl, "solid x\nendsolid x\n")?;
        assert_eq!(source_id(&stl, "abc")?, "abc");
        Ok(())
    }
}
