//! A job's own files: its config ([`config`]), its folder's layout ([`layout`]), its frozen
//! manifest's records ([`manifest`]) and a shard's completion record ([`completion`]).

pub mod completion;
pub mod config;
pub mod layout;
pub mod manifest;
