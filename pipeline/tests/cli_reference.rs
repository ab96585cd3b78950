//! The generated command reference (docs/CLI.md), man pages and completions: the reference
//! in the repository is what `sparc3d generate reference` writes, each of its blocks is what
//! the binary's own `--help` prints, and the man pages and completion scripts name every
//! command.

mod common;

use common::{ok, sparc3d};
use std::path::Path;

fn reference_file() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/CLI.md");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

/// `(command words, help text)` of every section of the reference.
fn sections(reference: &str) -> Vec<(Vec<String>, String)> {
    let mut out = Vec::new();
    for part in reference.split("\n## `").skip(1) {
        let (title, rest) = part.split_once("`\n").unwrap_or_default();
        let body = rest
            .split_once("```text\n")
            .and_then(|(_, b)| b.split_once("\n```"))
            .map(|(b, _)| b.to_string())
            .unwrap_or_default();
        let words = title.split(' ').skip(1).map(str::to_string).collect();
        out.push((words, body));
    }
    out
}

/// The commands `sparc3d --help` lists (hidden ones and `help` aside).
fn listed_commands() -> Vec<String> {
    let help = ok(&["--help"]);
    let listing = help
        .split("Commands:\n")
        .nth(1)
        .and_then(|s| s.split("\n\n").next())
        .unwrap_or_default();
    listing
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

#[test]
fn the_reference_in_the_repository_is_what_generate_writes() {
    let generated = ok(&["generate", "reference"]);
    assert!(
        generated == reference_file(),
        "docs/CLI.md is out of date: run `sparc3d generate reference -o docs/CLI.md`"
    );
}

#[test]
fn every_section_of_the_reference_is_what_help_prints_and_every_command_has_one() {
    let reference = reference_file();
    let sections = sections(&reference);
    for (words, body) in &sections {
        let mut args: Vec<&str> = words.iter().map(String::as_str).collect();
        args.push("--help");
        let printed = ok(&args);
        assert_eq!(printed.trim_end(), body, "sparc3d {}", args.join(" "));
    }
    let documented: Vec<&str> = sections
        .iter()
        .filter(|(w, _)| w.len() == 1)
        .map(|(w, _)| w[0].as_str())
        .collect();
    assert_eq!(
        documented,
        listed_commands(),
        "commands and sections differ"
    );
    assert!(documented.contains(&"render") && documented.contains(&"generate"));
}

#[test]
fn the_man_pages_and_completions_name_every_command() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let out = dir.path().join("share");
    let out_text = out.to_string_lossy().to_string();
    ok(&["generate", "all", "--out", &out_text]);
    let read = |rel: &str| {
        std::fs::read_to_string(out.join(rel)).unwrap_or_else(|e| panic!("reading {rel}: {e}"))
    };
    let page = read("man/man1/sparc3d.1");
    assert!(
        page.starts_with(".ie") || page.contains(".TH sparc3d"),
        "{page:.200}"
    );
    assert_eq!(page, ok(&["generate", "man"]));
    let scripts = [
        read("bash-completion/completions/sparc3d"),
        read("zsh/site-functions/_sparc3d"),
        read("fish/vendor_completions.d/sparc3d.fish"),
    ];
    let pages = std::fs::read_dir(out.join("man/man1")).map_or(0, |d| d.count());
    assert_eq!(
        pages,
        1 + 2 + listed_commands().len(),
        "a page a command (and manifest build, submit slurm)"
    );
    for command in listed_commands() {
        // roff writes a hyphen as `\-`.
        let roff = command.replace('-', "\\-");
        assert!(page.contains(&roff), "the man page lacks {command}");
        let own = out.join(format!("man/man1/sparc3d-{command}.1"));
        assert!(own.is_file(), "no man page of {command}");
        for script in &scripts {
            assert!(script.contains(&command), "a completion lacks {command}");
        }
    }
    assert!(
        scripts[0].contains("--passes"),
        "bash completes render's flags"
    );
    let syntax = std::process::Command::new("bash")
        .arg("-n")
        .arg(out.join("bash-completion/completions/sparc3d"))
        .output()
        .expect("running bash -n");
    assert!(syntax.status.success(), "{:?}", syntax);
    let refused = sparc3d(&["generate", "all"]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--out"));
}
