//! The flags several commands share, each a clap `Args` struct that a command flattens into
//! its own: the job's config ([`config`]) and how its manifest's rows are read ([`source`]),
//! the per-item limits of a run ([`limits`]), the grid resolution ([`resolution`]), and the
//! conversion's switches ([`deform`], [`inside_test`], [`refine`]; the first two as one group
//! in [`conversion`]). A command's own flags stay in its module under `commands/`.

pub mod config;
pub mod conversion;
pub mod deform;
pub mod inside_test;
pub mod limits;
pub mod refine;
pub mod resolution;
pub mod source;
