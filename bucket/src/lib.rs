//! Jobs whose home is a bucket (`s3://`, `gs://`, `az://`): workers on machines that share
//! nothing but the bucket. The job's files have the keys of a job folder ([`keys`]); a
//! shard's lease is an object taken and renewed by conditional writes ([`lease`]); a worker
//! processes a shard in a scratch copy of the job exactly as on disk ([`work`]), uploading its
//! progress as checkpoint objects ([`checkpoint`]) and the finished shard under a name of its
//! own, committed by creating the completion record that names it ([`commit`]). `init`
//! uploads a job made locally ([`publish`]); the read-only commands read a local view
//! ([`view`]) from one listing of the job ([`listing`]) and the records it shows
//! ([`records`]), requests a few at a time ([`parallel`]), kept in a scratch folder per job
//! URL ([`scratch`]), trusted only while the
//! bucket still holds the objects it was copied from ([`integrity`]); `verify` hashes the
//! objects in the bucket ([`verify`]).
//!
//! docs/RELIABILITY.md, "Jobs in a bucket", says what is guaranteed; docs/CLUSTER.md how to
//! run one.
#![deny(missing_docs)]

pub mod checkpoint;
pub mod commit;
pub mod home;
pub mod integrity;
pub mod keys;
pub mod lease;
pub mod listing;
pub mod parallel;
pub mod publish;
pub mod quarantine;
pub mod records;
pub mod retry;
pub mod scratch;
pub mod verify;
pub mod view;
pub mod work;

pub use home::JobHome;
