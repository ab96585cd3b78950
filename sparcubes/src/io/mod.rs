//! Loading and saving meshes: OBJ, PLY, STL, OFF, glTF/GLB in; PLY, OBJ, STL, GLB out.
//!
//! [`load`] picks the reader by extension (case-insensitive), or by content when the extension
//! says nothing, and then [`crate::mesh::sanitize`]s what it read. Every reader takes the whole file as
//! bytes, never trusts a count from a header for an allocation, and turns anything it cannot
//! read into an [`Error`] that names the file; a panic inside a third-party parser is caught and
//! reported the same way. Only regular files are read ([`open_regular`]): a FIFO, a device or a
//! socket (also behind a link) is refused at once instead of blocking or reading forever.
//!
//! Every format follows one rule for faces whose vertex index is bad (out of range, negative,
//! not a number): the face is dropped and counted in [`LoadStats::faces_bad_index`], the first
//! one's place (format and line or element) is kept in [`LoadStats::first_bad_face`], and the
//! file fails ([`Error::EmptyMesh`]) only when no face is left. A triangle that repeats an
//! earlier one (same vertex indices) is dropped and counted in [`LoadStats::faces_duplicate`].
//! [`save`] writes to a temporary file beside the target and renames it.

pub(crate) mod gltf;
mod obj;
mod off;
mod ply;
mod ply_error;
mod stl;
mod write;

pub use write::PendingSave;

use crate::error::{Error, Result};
use crate::mesh::duplicate_faces::drop_duplicate_faces;
use crate::mesh::sanitize::drop_invalid;
use crate::mesh::TriMesh;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// Largest input file read, in bytes.
pub const MAX_FILE_BYTES: u64 = 4 << 30;
/// Largest number of vertices or triangles a loaded mesh may have.
pub const MAX_ELEMENTS: usize = 200_000_000;

/// What loading skipped or repaired, for the conversion summary and shard rows.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LoadStats {
    /// Polygons with more than three corners that were triangulated.
    pub polygons_triangulated: u64,
    /// Point primitives skipped.
    pub points_skipped: u64,
    /// Line primitives skipped (segments).
    pub lines_skipped: u64,
    /// Faces dropped because a vertex index was bad (out of range, negative, not a number).
    pub faces_bad_index: u64,
    /// Where the first such face is: format and line or element (e.g. `OBJ line 7: vertex
    /// index 9, the file has 3 vertices`).
    pub first_bad_face: Option<String>,
    /// Faces dropped because a corner had a non-finite coordinate.
    pub faces_non_finite: u64,
    /// Vertices dropped because no kept face used them.
    pub vertices_unused: u64,
    /// Triangles dropped because an earlier one has the same three vertex indices (in any
    /// order): [`crate::mesh::duplicate_faces`].
    pub faces_duplicate: u64,
    /// Vertices the file defines, when its reader keeps only those a face uses (OBJ): what
    /// an empty mesh's message counts.
    pub vertices_in_file: Option<u64>,
}

/// A loaded, sanitised mesh and what loading did to it.
#[derive(Debug, Clone, Default)]
pub struct LoadedMesh {
    /// The mesh (indices valid, coordinates finite, at least one triangle).
    pub mesh: TriMesh,
    /// What was skipped or repaired.
    pub stats: LoadStats,
}

/// The file formats [`load`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ (text).
    Obj,
    /// Stanford PLY (ascii or binary).
    Ply,
    /// STL (ascii or binary).
    Stl,
    /// Object File Format (text).
    Off,
    /// glTF 2.0, JSON (`.gltf`) or binary (`.glb`).
    Gltf,
}

impl Format {
    /// The format's usual name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Format::Obj => "OBJ",
            Format::Ply => "PLY",
            Format::Stl => "STL",
            Format::Off => "OFF",
            Format::Gltf => "glTF",
        }
    }

    /// The format named by a file extension (case-insensitive), if any.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "obj" => Format::Obj,
            "ply" => Format::Ply,
            "stl" => Format::Stl,
            "off" => Format::Off,
            "gltf" | "glb" => Format::Gltf,
            _ => return None,
        })
    }

    /// Guesses the format from the first bytes of a file.
    pub fn sniff(bytes: &[u8]) -> Option<Format> {
        let head = &bytes[..bytes.len().min(4096)];
        if head.starts_with(b"glTF") {
            return Some(Format::Gltf);
        }
        if head.starts_with(b"ply") {
            return Some(Format::Ply);
        }
        if stl::looks_binary(bytes) {
            return Some(Format::Stl);
        }
        let text = String::from_utf8_lossy(head);
        let trimmed = text.trim_start();
        if trimmed.starts_with("solid") {
            return Some(Format::Stl);
        }
        if trimmed.starts_with('{') && text.contains("\"asset\"") {
            return Some(Format::Gltf);
        }
        let first = trimmed.split_whitespace().next().unwrap_or("");
        if first.ends_with("OFF") && first.len() <= 8 {
            return Some(Format::Off);
        }
        if text
            .lines()
            .any(|l| l.starts_with("v ") || l.starts_with("f "))
        {
            return Some(Format::Obj);
        }
        None
    }
}

/// A parse error for `path`.
pub(crate) fn parse_err(path: &Path, reason: impl Into<String>) -> Error {
    Error::Parse {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// A too-large error for `path`.
pub(crate) fn too_large(path: &Path, reason: impl Into<String>) -> Error {
    Error::TooLarge {
        context: path.display().to_string(),
        reason: reason.into(),
    }
}

/// Fails when `count` elements of `what` exceed [`MAX_ELEMENTS`].
pub(crate) fn check_count(path: &Path, what: &str, count: usize) -> Result<()> {
    if count > MAX_ELEMENTS {
        return Err(too_large(
            path,
            format!("{count} {what} (the limit is {MAX_ELEMENTS})"),
        ));
    }
    Ok(())
}

/// Adds a polygon (as vertex indices) as a triangle fan. Points and lines are counted, not
/// added.
pub(crate) fn push_polygon(tris: &mut Vec<[u32; 3]>, poly: &[u32], stats: &mut LoadStats) {
    match poly.len() {
        0 => {}
        1 => stats.points_skipped += 1,
        2 => stats.lines_skipped += 1,
        3 => tris.push([poly[0], poly[1], poly[2]]),
        n => {
            stats.polygons_triangulated += 1;
            for k in 1..n - 1 {
                tris.push([poly[0], poly[k], poly[k + 1]]);
            }
        }
    }
}

/// Counts a face dropped for a bad vertex index; `place` (format and line or element) is
/// asked for only for the first one.
pub(crate) fn bad_face(stats: &mut LoadStats, place: impl FnOnce() -> String) {
    stats.faces_bad_index += 1;
    if stats.first_bad_face.is_none() {
        stats.first_bad_face = Some(place());
    }
}

/// What a file-system object is, when it is not a regular file.
fn special_kind(kind: &std::fs::FileType) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_file() {
        None
    } else if kind.is_dir() {
        Some("a folder")
    } else if kind.is_fifo() {
        Some("a FIFO (named pipe)")
    } else if kind.is_char_device() {
        Some("a character device")
    } else if kind.is_block_device() {
        Some("a block device")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        Some("not a regular file")
    }
}

/// Opens `path` for reading if it is a regular file once links are followed, and returns it
/// with its size. A FIFO, device, socket or folder is refused with an error naming what it
/// is, without a blocking open (the kind is checked before opening, the open does not wait
/// for a FIFO's writer, and the opened file is checked again).
pub fn open_regular(path: &Path) -> std::io::Result<(std::fs::File, u64)> {
    let refuse = |what: &str| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{what}, not a regular file; only regular files are read"),
        )
    };
    if let Some(what) = special_kind(&std::fs::metadata(path)?.file_type()) {
        return Err(refuse(what));
    }
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let meta = file.metadata()?;
    if let Some(what) = special_kind(&meta.file_type()) {
        return Err(refuse(what));
    }
    Ok((file, meta.len()))
}

/// Bytes read from the start of a file before the rest, for checks that can refuse the file
/// without reading it whole ([`stl::empty_by_header`]).
const HEAD_BYTES: u64 = 1024;

/// Reads a mesh file's bytes as [`load`] does, for a caller that needs the bytes themselves
/// (the job's worker hashes what it converts) before [`load_read`] parses them: `read_file`,
/// except that a `.stl` whose binary header claims no triangle is refused as an empty mesh
/// after its first kilobyte, however long the file is.
pub fn read_source(path: &Path) -> Result<Vec<u8>> {
    let stl = Format::from_extension(path) == Some(Format::Stl);
    read_checked(path, |head, len| {
        let reason = stl.then(|| stl::empty_by_header(head, len)).flatten()?;
        Some(Error::EmptyMesh {
            context: path.display().to_string(),
            reason,
        })
    })
}

/// Reads a regular file whole ([`open_regular`]), refusing files over [`MAX_FILE_BYTES`]
/// (also one that grows past it while being read) and empty files.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>> {
    read_checked(path, |_, _| None)
}

/// [`read_file`], reading the first [`HEAD_BYTES`] first: `refuse` sees them and the file's
/// length, and an error it returns ends the read there.
pub(crate) fn read_checked(
    path: &Path,
    refuse: impl Fn(&[u8], u64) -> Option<Error>,
) -> Result<Vec<u8>> {
    use std::io::Read;
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
        return Err(parse_err(path, "is a directory, not a mesh file"));
    }
    let (mut file, len) = open_regular(path).map_err(io_err)?;
    let over = |len: u64| {
        too_large(
            path,
            format!("file is {len} bytes (the limit is {MAX_FILE_BYTES})"),
        )
    };
    if len > MAX_FILE_BYTES {
        return Err(over(len));
    }
    let mut head = Vec::with_capacity(HEAD_BYTES as usize);
    file.by_ref()
        .take(HEAD_BYTES)
        .read_to_end(&mut head)
        .map_err(io_err)?;
    if let Some(e) = refuse(&head, len) {
        return Err(e);
    }
    let mut bytes = Vec::with_capacity(len.max(head.len() as u64) as usize);
    bytes.extend_from_slice(&head);
    drop(head);
    file.take(MAX_FILE_BYTES + 1 - bytes.len() as u64)
        .read_to_end(&mut bytes)
        .map_err(io_err)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(over(bytes.len() as u64));
    }
    if bytes.is_empty() {
        return Err(parse_err(path, "empty file"));
    }
    Ok(bytes)
}

/// Why a load ended with no triangle: what was dropped or skipped, and where the first face
/// with a bad vertex index is.
fn empty_reason(format: Format, stats: &LoadStats, vertices: usize) -> String {
    let mut reason = format!(
        "no valid triangle in this {} file ({vertices} vertices",
        format.name()
    );
    if stats.faces_bad_index > 0 {
        reason.push_str(&format!(
            "; dropped {} faces with a bad vertex index, the first at {}",
            stats.faces_bad_index,
            stats
                .first_bad_face
                .as_deref()
                .unwrap_or("an unknown place")
        ));
    }
    if stats.faces_non_finite > 0 {
        reason.push_str(&format!(
            "; dropped {} faces with a non-finite coordinate",
            stats.faces_non_finite
        ));
    }
    if stats.points_skipped + stats.lines_skipped > 0 {
        reason.push_str(&format!(
            "; skipped {} points and {} line segments",
            stats.points_skipped, stats.lines_skipped
        ));
    }
    let dropped = stats.faces_bad_index + stats.faces_non_finite;
    if dropped + stats.points_skipped + stats.lines_skipped == 0 {
        reason.push_str(" and no face");
    }
    reason.push(')');
    reason
}

/// Loads a mesh file, choosing the format by extension (then by content), and sanitises it.
pub fn load(path: &Path) -> Result<LoadedMesh> {
    load_read(&read_source(path)?, path)
}

/// Where a glTF file's external buffers (`"uri": "scene.bin"`) are read from.
#[derive(Clone, Copy)]
pub enum Buffers<'a> {
    /// From disk, inside the glTF file's own folder (links followed and checked).
    Folder,
    /// From a reader given the buffer's path relative to the glTF file, already checked
    /// (plain components: no `..`, not absolute, no scheme): for a file fetched from a URL,
    /// whose reader fetches the sibling object under the same prefix. Its error text is
    /// kept in the parse error.
    Relative(&'a dyn Fn(&str) -> std::result::Result<Vec<u8>, String>),
}

impl std::fmt::Debug for Buffers<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Buffers::Folder => "Buffers::Folder",
            Buffers::Relative(_) => "Buffers::Relative",
        })
    }
}

/// Parses and sanitises the bytes [`read_source`] read from `path`, choosing the format by
/// the extension of `path` (then by content); `path` names the file in errors and locates a
/// glTF file's external buffers.
pub fn load_read(bytes: &[u8], path: &Path) -> Result<LoadedMesh> {
    load_read_with(bytes, path, Buffers::Folder)
}

/// [`load_read`] with a glTF file's external buffers read from `buffers`.
pub fn load_read_with(bytes: &[u8], path: &Path, buffers: Buffers) -> Result<LoadedMesh> {
    let format = match Format::from_extension(path) {
        Some(f) => f,
        None => Format::sniff(bytes).ok_or_else(|| Error::UnsupportedFormat {
            path: path.to_path_buf(),
            reason: "unknown extension and unrecognised content (supported: .obj, .ply, \
                     .stl, .off, .gltf, .glb)"
                .to_string(),
        })?,
    };
    load_bytes_with(bytes, format, path, buffers)
}

/// Reads and sanitises a mesh of a known format from bytes; `path` names it in errors and
/// locates a glTF file's external buffers.
pub fn load_bytes(bytes: &[u8], format: Format, path: &Path) -> Result<LoadedMesh> {
    load_bytes_with(bytes, format, path, Buffers::Folder)
}

/// [`load_bytes`] with a glTF file's external buffers read from `buffers`.
pub fn load_bytes_with(
    bytes: &[u8],
    format: Format,
    path: &Path,
    buffers: Buffers,
) -> Result<LoadedMesh> {
    let raw = catch_unwind(AssertUnwindSafe(|| {
        let mut stats = LoadStats::default();
        let mesh = match format {
            Format::Obj => obj::read(bytes, path, &mut stats),
            Format::Ply => ply::read(bytes, path, &mut stats),
            Format::Stl => stl::read(bytes, path, &mut stats),
            Format::Off => off::read(bytes, path, &mut stats),
            Format::Gltf => gltf::read(bytes, path, buffers, &mut stats),
        };
        mesh.map(|m| (m, stats))
    }))
    .map_err(|panic| {
        let msg = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        parse_err(path, format!("the {format:?} parser failed: {msg}"))
    })??;
    let (raw, mut stats) = raw;
    check_count(path, "vertices", raw.positions.len())?;
    check_count(path, "triangles", raw.triangles.len())?;
    let context = path.display().to_string();
    let vertices = stats
        .vertices_in_file
        .map_or(raw.positions.len(), |n| n as usize);
    let (mut mesh, s) = drop_invalid(raw);
    stats.faces_duplicate = drop_duplicate_faces(&mut mesh.triangles);
    // Loaders drop faces with bad indices themselves; what sanitising finds adds to that.
    stats.faces_bad_index += s.faces_bad_index;
    stats.faces_non_finite += s.faces_non_finite;
    stats.vertices_unused += s.vertices_unused;
    if mesh.triangles.is_empty() {
        return Err(Error::EmptyMesh {
            context,
            reason: empty_reason(format, &stats, vertices),
        });
    }
    Ok(LoadedMesh { mesh, stats })
}

/// Saves a mesh; the format follows the extension (`.ply`, `.obj`, `.stl`, `.glb`).
///
/// The file is written to a temporary name in the same folder and renamed, so a failed write
/// never leaves a partial file behind.
pub fn save(mesh: &TriMesh, path: &Path) -> Result<()> {
    write::save_pending(mesh, None, path)?.commit()
}

/// Saves a mesh as [`save`] does, with one colour per vertex (sRGB and alpha bytes) where the
/// format holds vertex colours: PLY (`red`, `green`, `blue`, `alpha`), OBJ (`v x y z r g b`)
/// and GLB (`COLOR_0`, linear); an STL is written without them ([`holds_colours`] says).
pub fn save_coloured(mesh: &TriMesh, colours: &[[u8; 4]], path: &Path) -> Result<()> {
    write::save_pending(mesh, Some(colours), path)?.commit()
}

/// Whether the format of `path` (by its extension) holds vertex colours.
pub fn holds_colours(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("ply" | "obj" | "glb"))
}

/// Writes a mesh as [`save`] does (with `colours` as [`save_coloured`] writes them) but stops
/// before the sync and the rename: the returned
/// [`PendingSave`] puts the file in place when committed, and removes it when dropped
/// uncommitted. For callers with work to do while the disk catches up.
pub fn save_pending(
    mesh: &TriMesh,
    colours: Option<&[[u8; 4]]>,
    path: &Path,
) -> Result<PendingSave> {
    write::save_pending(mesh, colours, path)
}

/// A PLY parser error in words, without Rust debug notation ([`ply_error::plain`]).
pub(crate) fn plain_ply_error(text: &str) -> String {
    ply_error::plain(text)
}
