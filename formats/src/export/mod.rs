//! Writing an export folder: what `sparc3d export` does with the items' files once a
//! consumer has made them. An export is built in a folder beside its destination
//! ([`Staging`]) and moved into place at the end, so the destination is never half written:
//! it is either absent, or a finished export, or (after a rerun) the new finished export.
//! [`RECORD`] in it says which job, consumer, frame and items it holds, beside the
//! consumer's listing files ([`Staging::finish`]); [`debris`] clears what killed exports
//! left beside it. Reading the job's rows and making each item's files is the caller's
//! (the `export` command), through [`crate::Consumer::files`].

pub mod debris;
mod folder;
mod record;

pub use folder::Staging;
pub use record::{ItemOutcome, Outcome, Record, Written};

/// The file that marks a folder as a finished export and says what it holds.
/// Hidden, so a loader that globs the folder for items (Hunyuan3D-2.1's) never meets it.
pub const RECORD: &str = ".sparc3d-export.json";

/// An [`crate::Error::Io`] saying what was being done.
pub(crate) fn io(context: String) -> impl FnOnce(std::io::Error) -> crate::Error {
    move |source| crate::Error::Io { context, source }
}
