//! Loads every mesh of a corpus and checks its face count against the corpus manifest (a TSV
//! with `out_name` and `faces` columns, as the dev corpus of docs/QUALITY.md has). The corpus
//! is not in the repository, so the test is ignored by default; asked for, it needs both
//! variables and fails without them:
//!
//! ```text
//! SPARC3D_CORPUS=/path/to/corpus/dev SPARC3D_CORPUS_MANIFEST=/path/to/dev_manifest.tsv \
//!     cargo test -p sparcubes --test io_corpus -- --ignored --nocapture
//! ```

use std::path::PathBuf;

fn env_path(name: &str) -> PathBuf {
    match std::env::var_os(name) {
        Some(v) => PathBuf::from(v),
        None => panic!("{name} is not set: this test needs the corpus (see the file's doc)"),
    }
}

#[test]
#[ignore = "needs the dev corpus; set SPARC3D_CORPUS and SPARC3D_CORPUS_MANIFEST"]
fn corpus_face_counts() {
    let (dir, manifest) = (
        env_path("SPARC3D_CORPUS"),
        env_path("SPARC3D_CORPUS_MANIFEST"),
    );
    let text = std::fs::read_to_string(&manifest)
        .unwrap_or_else(|e| panic!("{}: {e}", manifest.display()));
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap_or_default().split('\t').collect();
    let col = |name: &str| {
        head.iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("{}: no column {name}", manifest.display()))
    };
    let (c_name, c_faces) = (col("out_name"), col("faces"));
    let (mut ok, mut no_buffer) = (0, 0);
    let mut problems = Vec::new();
    for line in lines.filter(|l| !l.is_empty()) {
        let f: Vec<&str> = line.split('\t').collect();
        let (name, faces) = (f[c_name], f[c_faces]);
        let path = dir.join(name);
        let Ok(want) = faces.parse::<usize>() else {
            problems.push(format!("{name}: manifest faces {faces:?} is not a number"));
            continue;
        };
        let t = std::time::Instant::now();
        match sparcubes::io::load(&path) {
            Ok(m) if m.mesh.face_count() == want => ok += 1,
            Ok(m) => problems.push(format!(
                "{name}: {} faces, the manifest says {want} ({:?})",
                m.mesh.face_count(),
                m.stats
            )),
            // A `.gltf` copied without its `.bin` cannot be read; that is the copy's fault.
            Err(e) if e.to_string().contains("cannot read buffer") => {
                no_buffer += 1;
                println!("NO BUFFER {name}: {e}");
            }
            Err(e) => problems.push(format!("{name}: failed ({}): {e}", e.class().as_str())),
        }
        if t.elapsed().as_secs_f64() > 2.0 {
            println!("SLOW {name} {:.1}s", t.elapsed().as_secs_f64());
        }
    }
    println!(
        "{ok} ok, {no_buffer} without their buffer, {} wrong",
        problems.len()
    );
    assert!(ok > 0, "no mesh of {} loaded", dir.display());
    assert!(
        problems.is_empty(),
        "{} of {} meshes wrong:\n{}",
        problems.len(),
        ok + no_buffer + problems.len(),
        problems.join("\n")
    );
}
