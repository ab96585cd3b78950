//! Texture files are refused from their length and header before they are read whole
//! (issue 64 item 4): a file longer than any image decoded here (`image::MAX_FILE_BYTES`,
//! made sparse so the test writes nothing of it) costs a length check, not a read of
//! hundreds of megabytes; the mesh's shape and its other materials are still read.

use sparcubes::io::Buffers;
use sparcubes::materials::{self, image::MAX_FILE_BYTES};
use std::path::Path;

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// A 2 × 2 PNG, all red.
fn red_png() -> Result<Vec<u8>, Box<dyn std::error::Error>> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, 2, 2);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header()?;
    writer.write_image_data(&[255, 0, 0, 255].repeat(4))?;
    writer.finish()?;
    Ok(out)
}

/// A quad whose material reads `texture` as its base colour.
fn textured_quad(dir: &Path, texture: &str) -> std::io::Result<std::path::PathBuf> {
    std::fs::write(
        dir.join("m.mtl"),
        format!("newmtl t\nKd 1 1 1\nmap_Kd {texture}\n"),
    )?;
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl t\nf 1/1 2/2 3/3 4/4\n";
    let path = dir.join("quad.obj");
    std::fs::write(&path, obj)?;
    Ok(path)
}

#[test]
fn a_texture_file_longer_than_any_image_is_refused_before_it_is_read() -> TestResult {
    let dir = tempfile::tempdir()?;
    let file = std::fs::File::create(dir.path().join("huge.png"))?;
    std::io::Write::write_all(&mut &file, &red_png()?)?;
    file.set_len(MAX_FILE_BYTES + 1)?;
    let path = textured_quad(dir.path(), "huge.png")?;
    let bytes = std::fs::read(&path)?;
    let app = materials::read(&bytes, &path, Buffers::Folder)?;
    assert_eq!(app.facts.materials, 1);
    assert!(!app.facts.textured(), "{:?}", app.facts);
    let said = app.facts.not_read.join("; ");
    assert!(
        said.contains("huge.png") && said.contains("more than any image"),
        "{said}"
    );
    // The same file at its own length is read and sampled.
    let small = std::fs::File::options()
        .write(true)
        .open(dir.path().join("huge.png"))?;
    small.set_len(red_png()?.len() as u64)?;
    let app = materials::read(&bytes, &path, Buffers::Folder)?;
    assert!(
        app.facts.textured() && app.facts.not_read.is_empty(),
        "{:?}",
        app.facts
    );
    Ok(())
}
