//! Loads every mesh of a corpus and compares face counts with its manifest. Needs the dev
//! corpus (docs/QUALITY.md says what it is), so it is ignored by default:
//!
//! ```text
//! SPARC3D_CORPUS=/tmp/corpus/dev SPARC3D_CORPUS_MANIFEST=.../dev_manifest.tsv \
//!     cargo test -p sparcubes --test io_corpus -- --ignored --nocapture
//! ```

use std::path::PathBuf;

#[test]
#[ignore = "needs the dev corpus; set SPARC3D_CORPUS and SPARC3D_CORPUS_MANIFEST"]
fn corpus_face_counts() {
    let (Ok(dir), Ok(manifest)) = (
        std::env::var("SPARC3D_CORPUS"),
        std::env::var("SPARC3D_CORPUS_MANIFEST"),
    ) else {
        eprintln!("SPARC3D_CORPUS / SPARC3D_CORPUS_MANIFEST not set; nothing to do");
        return;
    };
    let text = std::fs::read_to_string(&manifest).expect("manifest");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split('\t').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).expect("column");
    let (c_name, c_faces) = (col("out_name"), col("faces"));
    let (mut ok, mut mismatch, mut failed) = (0, 0, 0);
    for line in lines {
        let f: Vec<&str> = line.split('\t').collect();
        let path = PathBuf::from(&dir).join(f[c_name]);
        let want: usize = f[c_faces].parse().unwrap_or(0);
        let t = std::time::Instant::now();
        match sparcubes::io::load(&path) {
            Ok(m) => {
                let got = m.mesh.face_count();
                if got == want {
                    ok += 1;
                } else {
                    mismatch += 1;
                    println!("MISMATCH {} got {got} want {want} {:?}", f[c_name], m.stats);
                }
                if t.elapsed().as_secs_f64() > 2.0 {
                    println!("SLOW {} {:.1}s", f[c_name], t.elapsed().as_secs_f64());
                }
            }
            // A `.gltf` copied without its `.bin` cannot be read; that is the copy's fault.
            Err(e) if e.to_string().contains("cannot read buffer") => {
                println!("NO BUFFER {}: {e}", f[c_name]);
            }
            Err(e) => {
                failed += 1;
                println!("FAILED {} ({}): {e}", f[c_name], e.class().as_str());
            }
        }
    }
    println!("{ok} ok, {mismatch} face-count mismatches, {failed} failed");
    assert_eq!(failed, 0);
}
