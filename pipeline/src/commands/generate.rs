//! `sparc3d generate WHAT [-o PATH]`: the man page, the shell completions and the command
//! reference, each derived from the clap definition that parses the command line and prints
//! `--help`, so none of them can say other than the binary does (`clap_mangen`,
//! `clap_complete`). `generate all --out DIR` writes the man pages and the three completion
//! scripts where a system or a user prefix keeps them (`DIR` = `~/.local/share` for one user).

use anyhow::{Context, Result};
use clap::CommandFactory;
use clap_complete::Shell;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// What `generate` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum What {
    /// The man page `sparc3d.1` (roff), the commands listed.
    Man,
    /// The bash completion script.
    Bash,
    /// The zsh completion script (`_sparc3d`).
    Zsh,
    /// The fish completion script.
    Fish,
    /// Every command's `--help` as one Markdown page (docs/CLI.md).
    Reference,
    /// A man page per command (`sparc3d.1`, `sparc3d-init.1`, …) and the three completion scripts, under `--out DIR` as
    /// `man/man1/`, `bash-completion/completions/`, `zsh/site-functions/` and
    /// `fish/vendor_completions.d/`.
    All,
}

/// Arguments of `sparc3d generate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to write.
    #[arg(value_enum)]
    pub what: What,
    /// The file to write (the folder for `all`, e.g. `~/.local/share`); standard output when
    /// not given.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
}

/// The command line's definition, built as `sparc3d` (subcommands named `sparc3d NAME`).
fn definition() -> clap::Command {
    let mut command = super::Cli::command();
    command.build();
    command
}

/// Runs `sparc3d generate`.
pub fn run(args: Args) -> Result<ExitCode> {
    let command = definition();
    let bytes = match args.what {
        What::Man => man_page(&command, "sparc3d")?,
        What::Bash => completion(&command, Shell::Bash),
        What::Zsh => completion(&command, Shell::Zsh),
        What::Fish => completion(&command, Shell::Fish),
        What::Reference => reference(&command).into_bytes(),
        What::All => {
            let dir = args
                .out
                .context("generate all: name the folder to write into with --out DIR")?;
            write_all(&command, &dir)?;
            eprintln!(
                "man pages and bash, zsh and fish completions written under {}",
                dir.display()
            );
            return Ok(ExitCode::SUCCESS);
        }
    };
    match &args.out {
        Some(path) => write_file(path, &bytes)?,
        None => {
            use std::io::Write;
            std::io::stdout()
                .write_all(&bytes)
                .context("writing to standard output")?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The roff man page of `command` (its own page, its subcommands listed), titled `title`.
fn man_page(command: &clap::Command, title: &str) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    clap_mangen::Man::new(command.clone())
        .title(title.to_string())
        .source(concat!("sparc3d ", env!("CARGO_PKG_VERSION")))
        .render(&mut bytes)
        .context("rendering the man page")?;
    Ok(bytes)
}

/// The completion script of `command` for `shell`.
fn completion(command: &clap::Command, shell: Shell) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut command = command.clone();
    clap_complete::generate(shell, &mut command, "sparc3d", &mut bytes);
    bytes
}

/// The commands a user runs, as the words after `sparc3d`: every subcommand not hidden (and
/// not clap's own `help`), nested ones after their parent.
fn visible(command: &clap::Command, path: &[String]) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for sub in command.get_subcommands() {
        if sub.is_hide_set() || sub.get_name() == "help" {
            continue;
        }
        let mut words = path.to_vec();
        words.push(sub.get_name().to_string());
        out.push(words.clone());
        out.extend(visible(sub, &words));
    }
    out
}

/// The subcommand `words` name (`["manifest", "build"]`).
fn subcommand<'a>(command: &'a clap::Command, words: &[String]) -> Option<&'a clap::Command> {
    words
        .iter()
        .try_fold(command, |c, w| c.find_subcommand(w.as_str()))
}

/// What `sparc3d WORDS --help` prints, asked of the definition itself.
fn help_of(command: &clap::Command, words: &[String]) -> String {
    let argv = std::iter::once("sparc3d".to_string())
        .chain(words.iter().cloned())
        .chain(["--help".to_string()]);
    match command.clone().try_get_matches_from(argv) {
        Err(e) => e.render().to_string(),
        Ok(_) => String::new(),
    }
}

/// The command reference: `sparc3d --help`, then each command's `--help` as it prints it.
pub fn reference(command: &clap::Command) -> String {
    let mut page = String::from(
        "# Command reference\n\n\
         Every command's `--help`, as the binary prints it. Generated by `sparc3d generate \
         reference -o docs/CLI.md`; do not edit (a test compares it with the binary). The \
         guide to the commands is [COMMANDS.md](COMMANDS.md).\n",
    );
    let mut all = vec![Vec::new()];
    all.extend(visible(command, &[]));
    for words in all {
        let name = std::iter::once("sparc3d")
            .chain(words.iter().map(String::as_str))
            .collect::<Vec<_>>()
            .join(" ");
        let help = help_of(command, &words);
        page.push_str(&format!(
            "\n## `{name}`\n\n```text\n{}\n```\n",
            help.trim_end()
        ));
    }
    page
}

/// The man pages and completion scripts under `dir`, in the layout of a `share` folder.
fn write_all(command: &clap::Command, dir: &Path) -> Result<()> {
    let man = dir.join("man/man1");
    std::fs::create_dir_all(&man).with_context(|| format!("creating {}", man.display()))?;
    write_file(&man.join("sparc3d.1"), &man_page(command, "sparc3d")?)?;
    for words in visible(command, &[]) {
        let Some(sub) = subcommand(command, &words) else {
            continue;
        };
        let name = format!("sparc3d-{}", words.join("-"));
        write_file(&man.join(format!("{name}.1")), &man_page(sub, &name)?)?;
    }
    for (shell, path) in [
        (Shell::Bash, "bash-completion/completions/sparc3d"),
        (Shell::Zsh, "zsh/site-functions/_sparc3d"),
        (Shell::Fish, "fish/vendor_completions.d/sparc3d.fish"),
    ] {
        write_file(&dir.join(path), &completion(command, shell))?;
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically, making its folder.
fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    sparc3d_workers::fsutil::write_atomic(path, bytes, "writing a generated file")?;
    Ok(())
}
