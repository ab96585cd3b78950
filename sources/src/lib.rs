//! Where an item's bytes come from. A manifest's `uri` is a local path, a `file://` URL, or a
//! remote object: `http(s)://host/path`, `s3://bucket/key`, `gs://bucket/key`,
//! `az://container/path` ([`location`]). Remote objects are fetched whole into memory (bucket
//! objects through the Arrow project's `object_store`, one client for S3, GCS and Azure;
//! `http(s)://` through reqwest, `http`) with connect and read time-outs, retries with
//! backoff on throttling, server errors and cut connections ([`limits`]), a byte cap checked
//! against the object's size before the body is read and again while it streams, and the
//! sha256 taken while it streams ([`fetch`]); a bucket prefix can be listed ([`list`]); the
//! objects of a job whose home is a bucket are read and written, conditionally where two
//! writers may race, through [`objects`].
//! Credentials come from the environment (and the usual files and metadata services), never
//! from a manifest, a job file or a URL ([`store`]).
//!
//! Errors are [`FetchError`]s naming the URL and what went wrong ([`error`]); the worker
//! records them as `failed` rows of class `fetch` (or `too_large` over the cap).
#![deny(missing_docs)]

mod aws_profile;
pub mod error;
pub mod fetch;
mod fetched;
mod http;
pub mod limits;
pub mod list;
pub mod location;
pub mod objects;
pub mod store;
mod tls;

pub use error::{FetchError, FetchErrorKind};
pub use fetch::{shared, Fetcher};
pub use fetched::Fetched;
pub use limits::FetchLimits;
pub use location::{Location, RemoteUrl, Scheme};
