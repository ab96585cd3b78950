//! The folder an export is built in, beside its destination, and the move of the finished
//! export into place.

use super::{debris, io, RECORD};
use crate::{Error, ExportFile, Result};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The folder an export is built in, beside its destination: `.NAME.partial-PID`.
#[derive(Debug)]
pub struct Staging {
    dir: PathBuf,
}

impl Staging {
    /// Creates the staging folder for `out` (removing one a killed export left); an error
    /// when `out` exists and is neither empty nor an earlier export (no [`RECORD`]): such a
    /// folder is never replaced.
    pub fn create(out: &Path) -> Result<Self> {
        refuse_a_folder_that_is_not_an_export(out)?;
        let dir = sibling(out, "partial")?;
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .map_err(io(format!("removing a stale {}", dir.display())))?;
        }
        std::fs::create_dir_all(&dir).map_err(io(format!("creating {}", dir.display())))?;
        Ok(Self { dir })
    }

    /// The folder itself.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes one file under the folder (its parent folders created) and fsyncs it.
    pub fn write(&self, file: &ExportFile) -> Result<()> {
        let path = self.dir.join(&file.path);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent)
                .map_err(io(format!("creating {}", parent.display())))?;
        }
        (|| -> std::io::Result<()> {
            let mut f = std::fs::File::create(&path)?;
            f.write_all(&file.bytes)?;
            f.sync_all()
        })()
        .map_err(io(format!("writing {}", path.display())))
    }

    /// Removes the staging folder (after an error).
    pub fn discard(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }

    /// Moves the finished export to `out`: swapped with an earlier export there in one step
    /// (which is then removed from the staging folder's name), or where the file system
    /// cannot, the earlier one moved aside first and removed after; `out` is always a whole
    /// export. An earlier export that cannot be removed (read-only) does not fail the export,
    /// which is complete and in place: what is left and where is handed back to be said.
    pub fn move_to(self, out: &Path) -> Result<Option<String>> {
        sync_tree(&self.dir)?;
        let old = sibling(out, "old")?;
        let replaced = out.exists();
        if replaced && debris::exchange(&self.dir, out)? {
            sync_parent(out)?;
            return Ok(remove_earlier(&self.dir, out));
        }
        if replaced {
            if old.exists() {
                std::fs::remove_dir_all(&old)
                    .map_err(io(format!("removing a stale {}", old.display())))?;
            }
            std::fs::rename(out, &old).map_err(io(format!(
                "moving {} aside to {}",
                out.display(),
                old.display()
            )))?;
        }
        std::fs::rename(&self.dir, out).map_err(io(format!(
            "moving {} to {}",
            self.dir.display(),
            out.display()
        )))?;
        sync_parent(out)?;
        Ok(replaced.then(|| remove_earlier(&old, out)).flatten())
    }
}

/// An error when `out` exists and is neither empty nor an earlier export (no [`RECORD`]).
fn refuse_a_folder_that_is_not_an_export(out: &Path) -> Result<()> {
    let mut entries = match std::fs::read_dir(out) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io(format!("reading {}", out.display()))(e)),
    };
    if entries.next().is_none() || out.join(RECORD).is_file() {
        return Ok(());
    }
    Err(Error::Invalid(format!(
        "{} holds files and is not an export (no {RECORD}); not overwritten: export into a \
         new or empty folder",
        out.display()
    )))
}

/// fsyncs the folder holding `out`, so that its new name is durable.
fn sync_parent(out: &Path) -> Result<()> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        sync_dir(parent)?;
    }
    Ok(())
}

/// fsyncs one folder.
fn sync_dir(dir: &Path) -> Result<()> {
    let f = std::fs::File::open(dir).map_err(io(format!("opening folder {}", dir.display())))?;
    f.sync_all()
        .map_err(io(format!("syncing folder {}", dir.display())))
}

/// Removes the earlier export of `out`, moved to `earlier`; `None` when it is gone, else what
/// is left there and why (the new export is in place either way).
fn remove_earlier(earlier: &Path, out: &Path) -> Option<String> {
    let err = std::fs::remove_dir_all(earlier).err()?;
    Some(format!(
        "the export in {} is complete; the earlier export it replaced could not be removed \
         from {} ({err}): remove it by hand",
        out.display(),
        earlier.display()
    ))
}

/// `.NAME.KIND-PID` beside `out`.
fn sibling(out: &Path, kind: &str) -> Result<PathBuf> {
    let Some(name) = out.file_name() else {
        return Err(Error::Invalid(format!(
            "--out {}: not a folder name",
            out.display()
        )));
    };
    let name = format!(".{}.{kind}-{}", name.to_string_lossy(), std::process::id());
    Ok(out.with_file_name(name))
}

/// fsyncs every folder under `dir` (the files were fsynced as written).
fn sync_tree(dir: &Path) -> Result<()> {
    let reading = || io(format!("reading {}", dir.display()));
    for entry in std::fs::read_dir(dir).map_err(reading())? {
        let entry = entry.map_err(reading())?;
        if entry.file_type().map(|t| t.is_dir()).unwrap_or(false) {
            sync_tree(&entry.path())?;
        }
    }
    sync_dir(dir)
}
