//! Writers: binary little-endian PLY, OBJ, binary STL and GLB, each written to a temporary
//! file beside the target, synced, then renamed over it.

use crate::colour::{srgb_to_linear, to_byte};
use crate::error::{Error, Result};
use crate::mesh::TriMesh;
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Output formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OutFormat {
    Ply,
    Obj,
    Stl,
    Glb,
}

/// Writes `mesh` in full to a temporary file beside `path` (the format follows its
/// extension), with `colours` (sRGB and alpha bytes, one per vertex) where the format holds
/// vertex colours (PLY, OBJ, GLB; not STL), leaving the sync and the rename to
/// [`PendingSave::commit`].
pub(crate) fn save_pending(
    mesh: &TriMesh,
    colours: Option<&[[u8; 4]]>,
    path: &Path,
) -> Result<PendingSave> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let format = match ext.as_deref() {
        Some("ply") => OutFormat::Ply,
        Some("obj") => OutFormat::Obj,
        Some("stl") => OutFormat::Stl,
        Some("glb") => OutFormat::Glb,
        _ => {
            return Err(Error::UnsupportedFormat {
                path: path.to_path_buf(),
                reason: "cannot write this extension (supported: .ply, .obj, .stl, .glb)"
                    .to_string(),
            })
        }
    };
    let n = mesh.positions.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(Error::InvalidParams(format!(
            "cannot save {}: triangle {t:?} has an index out of range ({n} vertices)",
            path.display()
        )));
    }
    if let Some(c) = colours.filter(|c| c.len() != n) {
        return Err(Error::InvalidParams(format!(
            "cannot save {}: {} vertex colours for {n} vertices",
            path.display(),
            c.len()
        )));
    }
    if format == OutFormat::Glb && (mesh.triangles.is_empty() || n == 0) {
        return Err(Error::EmptyMesh {
            context: path.display().to_string(),
            reason: "a GLB needs at least one triangle".to_string(),
        });
    }
    PendingSave::write(path, |w| match format {
        OutFormat::Ply => write_ply(mesh, colours, w),
        OutFormat::Obj => write_obj(mesh, colours, w),
        OutFormat::Stl => write_stl(mesh, w),
        OutFormat::Glb => write_glb(mesh, colours, w),
    })
}

/// A temporary name beside `path`, unique within this process and across processes.
fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let k = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}-{k}", std::process::id()))
}

/// A file written in full under a temporary name beside its target, not yet synced nor in
/// place. [`PendingSave::commit`] syncs it and renames it over the target; dropped without a
/// successful commit, it removes the temporary file and the target stays as it was. Splitting
/// the two lets the caller do other work while the disk catches up (the sync is most of a
/// large file's wall time).
pub struct PendingSave {
    path: PathBuf,
    tmp: PathBuf,
    file: Option<std::fs::File>,
    committed: bool,
}

impl PendingSave {
    /// Writes through `body` to a temporary file beside `path`; on error the temporary file
    /// is removed.
    fn write(
        path: &Path,
        body: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
    ) -> Result<Self> {
        let mut pending = Self {
            path: path.to_path_buf(),
            tmp: temp_path(path),
            file: None,
            committed: false,
        };
        let written = (|| {
            let file = std::fs::File::create(&pending.tmp)?;
            let mut w = std::io::BufWriter::new(file);
            body(&mut w)?;
            w.into_inner().map_err(|e| e.into_error())
        })();
        // On an error `pending` is dropped here, which removes the temporary file.
        pending.file = Some(written.map_err(|source| pending.io_error(source))?);
        Ok(pending)
    }

    /// Syncs the file to disk and renames it over the target. On error the temporary file is
    /// removed and the target is left as it was.
    pub fn commit(mut self) -> Result<()> {
        let synced = match self.file.take() {
            Some(file) => file.sync_all(),
            None => Ok(()),
        };
        synced
            .and_then(|()| std::fs::rename(&self.tmp, &self.path))
            .map_err(|source| self.io_error(source))?;
        self.committed = true;
        Ok(())
    }

    fn io_error(&self, source: std::io::Error) -> Error {
        Error::Io {
            path: self.path.clone(),
            source,
        }
    }
}

impl Drop for PendingSave {
    fn drop(&mut self) {
        if !self.committed {
            self.file = None;
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

fn write_ply(
    mesh: &TriMesh,
    colours: Option<&[[u8; 4]]>,
    w: &mut impl Write,
) -> std::io::Result<()> {
    let colour_properties = match colours {
        Some(_) => {
            "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
        }
        None => "",
    };
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment written by sparcubes\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n{colour_properties}\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    match colours {
        // `save_pending` checked one colour per vertex; encoded by index, without a copy of
        // the vertices zipped with their colours.
        Some(colours) => write_indexed(w, mesh.positions.len(), 16, |i, out| {
            for x in mesh.positions[i] {
                out.extend_from_slice(&x.to_le_bytes());
            }
            out.extend_from_slice(&colours[i]);
        })?,
        None => write_in_chunks(w, &mesh.positions, 12, |p, out| {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        })?,
    }
    write_in_chunks(w, &mesh.triangles, 13, |t, out| {
        out.push(3u8);
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    })
}

/// Elements encoded per parallel work item by [`write_in_chunks`].
const WRITE_CHUNK: usize = 1 << 16;
/// Work items encoded before they are written, bounding the memory held at once.
const WRITE_BATCH: usize = 16;

/// Writes `items` through `encode` (which appends `bytes_each` bytes per item), as
/// [`write_indexed`] writes them.
fn write_in_chunks<T: Sync>(
    w: &mut impl Write,
    items: &[T],
    bytes_each: usize,
    encode: impl Fn(&T, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    write_indexed(w, items.len(), bytes_each, |i, out| encode(&items[i], out))
}

/// Writes elements `0..len` through `encode` (which appends `bytes_each` bytes for element
/// `i`): chunks of [`WRITE_CHUNK`] are encoded in parallel, a batch at a time, and written in
/// order, so the bytes are those of a plain loop.
fn write_indexed(
    w: &mut impl Write,
    len: usize,
    bytes_each: usize,
    encode: impl Fn(usize, &mut Vec<u8>) + Sync,
) -> std::io::Result<()> {
    let batch_len = WRITE_CHUNK * WRITE_BATCH;
    for start in (0..len).step_by(batch_len) {
        let end = (start + batch_len).min(len);
        let encoded: Vec<Vec<u8>> = (start..end)
            .step_by(WRITE_CHUNK)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|from| {
                let to = (from + WRITE_CHUNK).min(end);
                let mut out = Vec::with_capacity((to - from) * bytes_each);
                for i in from..to {
                    encode(i, &mut out);
                }
                out
            })
            .collect();
        for bytes in &encoded {
            w.write_all(bytes)?;
        }
    }
    Ok(())
}

/// OBJ vertex colours are the common extension `v x y z r g b` (r, g, b in [0, 1], sRGB as
/// stored; alpha has no place), which MeshLab, Blender and trimesh read.
fn write_obj(
    mesh: &TriMesh,
    colours: Option<&[[u8; 4]]>,
    w: &mut impl Write,
) -> std::io::Result<()> {
    writeln!(w, "# written by sparcubes")?;
    // `{}` of an f32 prints the shortest text that reads back as the same f32.
    for (i, p) in mesh.positions.iter().enumerate() {
        match colours.and_then(|c| c.get(i)) {
            Some(c) => {
                let [r, g, b] = [c[0], c[1], c[2]].map(|x| f32::from(x) / 255.0);
                writeln!(w, "v {} {} {} {r} {g} {b}", p[0], p[1], p[2])?
            }
            None => writeln!(w, "v {} {} {}", p[0], p[1], p[2])?,
        }
    }
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

fn write_stl(mesh: &TriMesh, w: &mut impl Write) -> std::io::Result<()> {
    let mut header = [0u8; 80];
    let text = b"binary STL written by sparcubes";
    header[..text.len()].copy_from_slice(text);
    w.write_all(&header)?;
    let count = u32::try_from(mesh.triangles.len()).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "more than 2^32 triangles do not fit a binary STL",
        )
    })?;
    w.write_all(&count.to_le_bytes())?;
    for t in 0..mesh.triangles.len() {
        let n = mesh.face_normal(t);
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = if len > 0.0 {
            n.map(|x| (x / len) as f32)
        } else {
            [0.0; 3]
        };
        let mut rec = [0u8; 50];
        let corners = mesh.triangles[t].map(|i| mesh.positions[i as usize]);
        let floats = n.iter().chain(corners.iter().flatten());
        for (k, f) in floats.enumerate() {
            rec[4 * k..4 * k + 4].copy_from_slice(&f.to_le_bytes());
        }
        w.write_all(&rec)?;
    }
    Ok(())
}

/// glTF's `COLOR_0` is linear (glTF 2.0 spec, "Meshes", attribute semantics): the sRGB bytes
/// are turned to linear bytes, alpha kept, as normalised unsigned bytes.
fn write_glb(
    mesh: &TriMesh,
    colours: Option<&[[u8; 4]]>,
    w: &mut impl Write,
) -> std::io::Result<()> {
    let n = mesh.positions.len();
    let m = mesh.triangles.len();
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in &mesh.positions {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let pos_bytes = 12 * n;
    let idx_bytes = 12 * m;
    let colour_bytes = if colours.is_some() { 4 * n } else { 0 };
    let bin_len = pos_bytes + idx_bytes + colour_bytes;
    let mut json = glb_json(n, m, lo, hi, colours.is_some());
    json["buffers"] = serde_json::json!([{ "byteLength": bin_len }]);
    let mut json = serde_json::to_vec(&json).map_err(std::io::Error::other)?;
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let bin_padded = bin_len.div_ceil(4) * 4;
    let total = 12 + 8 + json.len() + 8 + bin_padded;
    let too_big = || std::io::Error::new(std::io::ErrorKind::InvalidInput, "GLB over 4 GiB");
    let u32_of = |x: usize| u32::try_from(x).map_err(|_| too_big());
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&u32_of(total)?.to_le_bytes())?;
    w.write_all(&u32_of(json.len())?.to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&json)?;
    w.write_all(&u32_of(bin_padded)?.to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    for p in &mesh.positions {
        for c in p {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    for t in &mesh.triangles {
        for i in t {
            w.write_all(&i.to_le_bytes())?;
        }
    }
    for c in colours.unwrap_or_default() {
        let linear = |x: u8| to_byte(srgb_to_linear(f32::from(x) / 255.0));
        w.write_all(&[linear(c[0]), linear(c[1]), linear(c[2]), c[3]])?;
    }
    w.write_all(&[0u8; 3][..bin_padded - bin_len])?;
    Ok(())
}

/// The GLB's JSON chunk (without its buffer's length): one primitive of `n` positions and `m`
/// triangles, with a `COLOR_0` of `n` linear RGBA bytes after them when `coloured`.
fn glb_json(n: usize, m: usize, lo: [f32; 3], hi: [f32; 3], coloured: bool) -> serde_json::Value {
    let (pos_bytes, idx_bytes) = (12 * n, 12 * m);
    let mut json = serde_json::json!({
        "asset": { "version": "2.0", "generator": "sparcubes" },
        "scene": 0,
        "scenes": [ { "nodes": [0] } ],
        "nodes": [ { "mesh": 0 } ],
        "meshes": [ { "primitives": [ { "attributes": { "POSITION": 0 }, "indices": 1, "mode": 4 } ] } ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
              "min": lo, "max": hi },
            { "bufferView": 1, "componentType": 5125, "count": 3 * m, "type": "SCALAR" }
        ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": pos_bytes, "target": 34962 },
            { "buffer": 0, "byteOffset": pos_bytes, "byteLength": idx_bytes, "target": 34963 }
        ]
    });
    if coloured {
        json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = serde_json::json!(2);
        if let Some(accessors) = json["accessors"].as_array_mut() {
            accessors.push(serde_json::json!({ "bufferView": 2, "componentType": 5121,
                "normalized": true, "count": n, "type": "VEC4" }));
        }
        if let Some(views) = json["bufferViews"].as_array_mut() {
            views.push(
                serde_json::json!({ "buffer": 0, "byteOffset": pos_bytes + idx_bytes,
                "byteLength": 4 * n, "target": 34962 }),
            );
        }
    }
    json
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PLY body, element by element, as the writer wrote it before chunking.
    fn plain_ply_body(mesh: &TriMesh) -> Vec<u8> {
        let mut out = Vec::new();
        for p in &mesh.positions {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &mesh.triangles {
            out.push(3);
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        out
    }

    /// The names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_pending_save_is_in_place_only_once_committed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.ply");
        std::fs::write(&target, b"old").unwrap();
        let mesh = crate::shapes::cuboid([0.0; 3], [1.0; 3], &[]);
        let mut plain = Vec::new();
        write_ply(&mesh, None, &mut plain).unwrap();

        // Written but dropped uncommitted: the temporary file goes, the target is untouched.
        let pending = save_pending(&mesh, None, &target).unwrap();
        assert_eq!(
            names(dir.path()).len(),
            2,
            "the temporary file is beside the target"
        );
        drop(pending);
        assert_eq!(names(dir.path()), ["out.ply"]);
        assert_eq!(std::fs::read(&target).unwrap(), b"old");

        // Committed: the target holds the mesh's bytes, nothing else is left.
        save_pending(&mesh, None, &target)
            .unwrap()
            .commit()
            .unwrap();
        assert_eq!(names(dir.path()), ["out.ply"]);
        assert_eq!(std::fs::read(&target).unwrap(), plain);

        // A commit that cannot rename (the target's folder is gone) fails and leaves nothing.
        let gone = dir.path().join("gone");
        std::fs::create_dir(&gone).unwrap();
        let pending = save_pending(&mesh, None, &gone.join("out.ply")).unwrap();
        std::fs::remove_dir_all(&gone).unwrap();
        assert!(pending.commit().is_err());
    }

    #[test]
    fn chunked_ply_is_the_plain_bytes() {
        // More elements than one batch of chunks, and not a multiple of a chunk.
        let n = WRITE_CHUNK * WRITE_BATCH + 12_345;
        let positions = (0..n)
            .map(|i| [i as f32, -(i as f32) * 0.5, (i % 977) as f32 * 1e-3])
            .collect();
        let triangles = (0..n as u32)
            .map(|i| [i, (i * 7 + 1) % n as u32, (i * 13 + 2) % n as u32])
            .collect();
        let mesh = TriMesh::new(positions, triangles);
        let mut written = Vec::new();
        write_ply(&mesh, None, &mut written).unwrap();
        let body = plain_ply_body(&mesh);
        assert!(written.ends_with(&body));
        let header = &written[..written.len() - body.len()];
        assert!(header.ends_with(b"end_header\n"));
    }

    #[test]
    fn chunked_coloured_ply_is_the_plain_bytes() {
        // Each vertex its position then its colour, element by element, over more than one
        // batch of chunks: the bytes the writer wrote when it zipped them into a copy first.
        let n = WRITE_CHUNK * WRITE_BATCH + 4_321;
        let positions: Vec<[f32; 3]> = (0..n).map(|i| [i as f32, 0.5, -(i as f32)]).collect();
        let colours: Vec<[u8; 4]> = (0..n).map(|i| [i as u8, (i >> 8) as u8, 7, 255]).collect();
        let mesh = TriMesh::new(positions.clone(), vec![[0, 1, 2]]);
        let mut written = Vec::new();
        write_ply(&mesh, Some(&colours), &mut written).unwrap();
        let mut body = Vec::new();
        for (p, c) in positions.iter().zip(&colours) {
            for x in p {
                body.extend_from_slice(&x.to_le_bytes());
            }
            body.extend_from_slice(c);
        }
        body.push(3);
        for i in [0u32, 1, 2] {
            body.extend_from_slice(&i.to_le_bytes());
        }
        assert!(written.ends_with(&body));
        let header = &written[..written.len() - body.len()];
        assert!(header.ends_with(b"property uchar alpha\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"));
    }
}
