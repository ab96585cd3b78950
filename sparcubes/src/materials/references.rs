//! The files a mesh file names beside itself and its readers read: an OBJ's material libraries
//! (`mtllib`) and the maps those name (`map_Kd`, `map_d`, `map_Pr`, `map_Pm`, as
//! [`super::mtl`] reads them), and a glTF's external buffers and images (`uri`s that are not
//! `data:`). An item made from a file is what these files and the mesh file's own bytes hold:
//! two folders with one OBJ and different textures are two items (`sparc3d_manifests`'
//! `source_id`).

use super::{mtl, sibling, Facts};
use crate::io::{Buffers, Format};
use serde_json::Value;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

/// A file named by a mesh file: the name as it is looked up ([`sibling::relative`]), and the
/// file on disk it resolves to, or why it cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NamedFile {
    /// The name, `\` read as `/`, `.` parts left out.
    pub name: String,
    /// The file beside the mesh file, or why it is not read.
    pub file: Result<PathBuf, String>,
}

/// The files the mesh file at `path` names, each once, in the order they are first named;
/// empty for formats that name none (STL, PLY, OFF, a `.glb` with every buffer and image
/// inside). Reads only what finds the names: an OBJ's `mtllib` lines (streamed), the libraries
/// themselves, and a glTF's JSON.
pub fn named_files(path: &Path) -> std::io::Result<Vec<NamedFile>> {
    let names = match Format::from_extension(path) {
        Some(Format::Obj) => obj_names(path)?,
        Some(Format::Gltf) => gltf_names(&gltf_json(path)?),
        _ => Vec::new(),
    };
    let mut out: Vec<NamedFile> = Vec::new();
    for name in names {
        let named = match sibling::relative(&name) {
            Ok(rel) => NamedFile {
                file: sibling::resolve(&rel, path),
                name: rel,
            },
            Err(why) => NamedFile {
                name: name.trim().replace('\\', "/"),
                file: Err(why),
            },
        };
        if !out.iter().any(|o| o.name == named.name) {
            out.push(named);
        }
    }
    Ok(out)
}

/// An OBJ's libraries, each followed by the maps it names.
fn obj_names(path: &Path) -> std::io::Result<Vec<String>> {
    let (file, _) = crate::io::open_regular(path)?;
    let mut reader = std::io::BufReader::new(file);
    let mut line = Vec::new();
    let mut names = Vec::new();
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line)? == 0 {
            break;
        }
        let text = String::from_utf8_lossy(&line);
        let mut words = text.split_whitespace();
        if words.next() == Some("mtllib") {
            let library = words.collect::<Vec<_>>().join(" ");
            let maps = library_maps(&library, path);
            names.push(library);
            names.extend(maps);
        }
    }
    Ok(names)
}

/// The maps the library `name` names ([`mtl::parse`]); none when it cannot be read.
fn library_maps(name: &str, path: &Path) -> Vec<String> {
    let Ok(bytes) = sibling::read(name, path, Buffers::Folder) else {
        return Vec::new();
    };
    let mut facts = Facts::default();
    mtl::parse(&String::from_utf8_lossy(&bytes), &mut facts)
        .into_iter()
        .flat_map(|m| m.maps.into_iter().map(|(_, spec)| spec.file))
        .collect()
}

/// The JSON of a `.gltf` file, or of a `.glb` file's JSON chunk (its header and that chunk
/// alone are read); `Null` when there is none.
fn gltf_json(path: &Path) -> std::io::Result<Value> {
    let (mut file, _) = crate::io::open_regular(path)?;
    let mut bytes = Vec::new();
    file.by_ref().take(20).read_to_end(&mut bytes)?;
    match super::gltf::glb_json_len(&bytes) {
        Some(len) => file.take(len as u64).read_to_end(&mut bytes)?,
        None => file.read_to_end(&mut bytes)?,
    };
    Ok(super::gltf::raw_json(&bytes))
}

/// The external `uri`s of a glTF's buffers, then of its images, percent-decoded.
fn gltf_names(json: &Value) -> Vec<String> {
    let uris = |key: &str| -> Vec<String> {
        let entries = json[key].as_array().map(Vec::as_slice).unwrap_or(&[]);
        entries
            .iter()
            .filter_map(|e| e["uri"].as_str())
            .filter(|uri| !uri.starts_with("data:"))
            .map(|uri| crate::io::gltf::percent_decode(uri).unwrap_or_else(|| uri.to_string()))
            .collect()
    };
    let mut names = uris("buffers");
    names.extend(uris("images"));
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(found: &[NamedFile]) -> Vec<&str> {
        found.iter().map(|f| f.name.as_str()).collect()
    }

    /// An OBJ names its library and the library's maps, each once, in order; a library that
    /// is missing is named with why it is not read.
    #[test]
    fn an_obj_names_its_libraries_and_their_maps() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let obj = dir.path().join("m.obj");
        std::fs::write(
            &obj,
            "mtllib a.mtl\nv 0 0 0\nmtllib .\\sub\\missing.mtl\nmtllib a.mtl\n",
        )?;
        std::fs::write(
            dir.path().join("a.mtl"),
            "newmtl x\nmap_Kd tex.png\nmap_d tex.png\nmap_Bump b.png\n",
        )?;
        std::fs::write(dir.path().join("tex.png"), b"png")?;
        let found = named_files(&obj)?;
        assert_eq!(names(&found), ["a.mtl", "tex.png", "sub/missing.mtl"]);
        assert!(found[1].file.is_ok());
        assert!(found[2].file.is_err());
        Ok(())
    }

    /// A `.gltf` names its external buffers and images, not its data URIs; `..` is refused.
    #[test]
    fn a_gltf_names_its_external_files() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let gltf = dir.path().join("m.gltf");
        let json = r#"{"buffers":[{"uri":"m.bin"},{"uri":"data:application/octet-stream;base64,AA=="}],
            "images":[{"uri":"a%20b.png"},{"uri":"../up.png"},{"bufferView":0}]}"#;
        std::fs::write(&gltf, json)?;
        let found = named_files(&gltf)?;
        assert_eq!(names(&found), ["m.bin", "a b.png", "../up.png"]);
        assert!(found[2].file.as_ref().is_err_and(|e| e.contains("..")));
        let stl = dir.path().join("m.stl");
        std::fs::write(&stl, "solid x\nendsolid x\n")?;
        assert!(named_files(&stl)?.is_empty());
        Ok(())
    }

    /// A `.glb` names the external images of its JSON chunk; the binary chunk after it is
    /// not read for names.
    #[test]
    fn a_glb_names_the_external_files_of_its_json_chunk() -> Result<(), Box<dyn std::error::Error>>
    {
        let dir = tempfile::tempdir()?;
        let json = br#"{"images":[{"uri":"t.png"}]}  "#;
        let bin = br#"{"images":[{"uri":"not_a_name.png"}]}"#;
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut glb = b"glTF".to_vec();
        for word in [2, total as u32, json.len() as u32] {
            glb.extend(word.to_le_bytes());
        }
        glb.extend(b"JSON");
        glb.extend(json);
        glb.extend((bin.len() as u32).to_le_bytes());
        glb.extend(b"BIN\0");
        glb.extend(bin);
        let path = dir.path().join("m.glb");
        std::fs::write(&path, glb)?;
        assert_eq!(names(&named_files(&path)?), ["t.png"]);
        Ok(())
    }
}
