//! Files named by a mesh file (an OBJ's material library, a texture, a glTF image), read only
//! from inside the mesh file's own folder, as glTF buffers are ([`crate::io`]): no absolute
//! path, no `..`, no URI scheme, and on disk a path that resolves (through links) inside the
//! folder; a file fetched from a URL reads its siblings through [`Buffers::Relative`].

use crate::io::Buffers;
use std::path::{Component, Path};

/// Reads the file `name` (relative to the mesh file at `path`; `\` read as `/`, as Windows
/// exporters write it), or says why not.
pub fn read(name: &str, path: &Path, buffers: Buffers) -> Result<Vec<u8>, String> {
    read_with(name, path, buffers, &|_, _| None)
}

/// [`read`] of a texture image: a file on disk is refused from its length and its first
/// bytes (its header's size) before it is read whole ([`super::image::refusal`]).
pub fn read_image(name: &str, path: &Path, buffers: Buffers) -> Result<Vec<u8>, String> {
    read_with(name, path, buffers, &super::image::refusal)
}

/// [`read`], with `refuse` shown the first bytes and the length of a file on disk first.
fn read_with(
    name: &str,
    path: &Path,
    buffers: Buffers,
    refuse: &dyn Fn(&[u8], u64) -> Option<String>,
) -> Result<Vec<u8>, String> {
    let rel = relative(name)?;
    if let Buffers::Relative(reader) = buffers {
        return reader(&rel);
    }
    let real = resolve(&rel, path)?;
    let refused =
        |head: &[u8], len: u64| refuse(head, len).map(|why| crate::io::too_large(&real, why));
    crate::io::read_checked(&real, refused).map_err(|e| e.to_string())
}

/// The name as it is looked up: `\` read as `/`, empty and `.` parts left out; refused when
/// it is empty, absolute, has a `..` part or a URI scheme.
pub fn relative(name: &str) -> Result<String, String> {
    let name = name.trim().replace('\\', "/");
    if name.is_empty() || name.contains('\0') {
        return Err("an empty name".into());
    }
    if let Some((scheme, _)) = name.split_once(':') {
        if scheme.len() > 1 && scheme.chars().all(|c| c.is_ascii_alphanumeric()) {
            return Err("only relative paths are read (it has a URI scheme)".into());
        }
    }
    if Path::new(&name)
        .components()
        .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err("absolute paths and `..` components are not read".into());
    }
    let plain: Vec<&str> = name
        .split('/')
        .filter(|p| !p.is_empty() && *p != ".")
        .collect();
    Ok(plain.join("/"))
}

/// The file on disk that the [`relative`] name `rel` names beside the mesh file at `path`,
/// links followed; refused when it resolves outside the mesh file's folder.
pub fn resolve(rel: &str, path: &Path) -> Result<std::path::PathBuf, String> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let real_dir = std::fs::canonicalize(dir).map_err(|e| e.to_string())?;
    let real = std::fs::canonicalize(dir.join(rel)).map_err(|e| format!("{e}"))?;
    if !real.starts_with(&real_dir) {
        return Err(format!(
            "it resolves to `{}`, outside the mesh file's folder",
            real.display()
        ));
    }
    Ok(real)
}

/// Short form of a name for messages.
pub fn clip(s: &str) -> String {
    let mut out: String = s.chars().take(80).collect();
    if out.len() < s.len() {
        out.push('…');
    }
    out
}
