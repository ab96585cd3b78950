//! The job in one home: a job folder made from manifest rows and a config ([`create`], the
//! rows frozen into slices as they are read: [`freeze_rows`]), the
//! config built from the flags ([`config`]), the rows it is made or grown from ([`rows`]),
//! grown under its lock ([`grow`]), set up for `run` and opened for the commands that read it
//! ([`setup`]), and a job whose home is a bucket ([`bucket_home`]). The commands (`init`,
//! `add`, `run`, the read-only ones) call in here; nothing here calls a command.

pub mod bucket_home;
pub mod config;
pub mod create;
pub mod freeze_rows;
pub mod grow;
pub mod rows;
pub mod setup;
