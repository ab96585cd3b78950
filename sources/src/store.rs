//! One `object_store` client per bucket, made on first use and kept for the
//! process, configured from the environment as each cloud's own tools are:
//!
//! - `s3://`: `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`, `AWS_REGION`
//!   / `AWS_DEFAULT_REGION`, `AWS_ENDPOINT_URL` (an S3-compatible store: MinIO, R2, Ceph,
//!   moto; `AWS_ALLOW_HTTP=true` or an `http://` endpoint allows plain HTTP),
//!   `AWS_SKIP_SIGNATURE=true` (public buckets); else the profile `AWS_PROFILE` of
//!   `~/.aws/credentials`, web identity (`AWS_WEB_IDENTITY_TOKEN_FILE`, `AWS_ROLE_ARN`), ECS
//!   container credentials, then the EC2 instance metadata service.
//! - `gs://`: `GOOGLE_SERVICE_ACCOUNT` (a key file), `GOOGLE_APPLICATION_CREDENTIALS`, the
//!   gcloud application-default credentials, then the GCE metadata server.
//! - `az://`: `AZURE_STORAGE_ACCOUNT_NAME` with `AZURE_STORAGE_ACCOUNT_KEY`, a SAS
//!   (`AZURE_STORAGE_SAS_KEY`), a client secret (`AZURE_CLIENT_ID`, `AZURE_CLIENT_SECRET`,
//!   `AZURE_TENANT_ID`), workload identity, or managed identity; `AZURE_STORAGE_ENDPOINT` for
//!   Azurite.
//!
//! Every client has the [`FetchLimits`]' time-outs and retries. `http(s)://` objects (no
//! credentials) are fetched by `http` with a client of its own, not through these.

use crate::error::{FetchError, FetchErrorKind};
use crate::limits::FetchLimits;
use crate::location::{RemoteUrl, Scheme};
use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::azure::MicrosoftAzureBuilder;
use object_store::gcp::GoogleCloudStorageBuilder;
use object_store::{BackoffConfig, ClientOptions, ObjectStore, RetryConfig};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The clients made so far, by scheme and bucket (or origin).
#[derive(Debug)]
pub struct Stores {
    limits: FetchLimits,
    made: Mutex<HashMap<(Scheme, String), Arc<dyn ObjectStore>>>,
}

impl Stores {
    /// No client yet; each will have `limits`.
    pub fn new(limits: FetchLimits) -> Self {
        crate::tls::install_provider();
        Self {
            limits,
            made: Mutex::new(HashMap::new()),
        }
    }

    /// The client for `url`'s bucket (or origin), made on first use.
    pub fn get(&self, url: &RemoteUrl) -> Result<Arc<dyn ObjectStore>, FetchError> {
        let key = (url.scheme, url.bucket());
        let mut made = self
            .made
            .lock()
            .map_err(|_| FetchError::new(url.to_string(), FetchErrorKind::Other, "poisoned"))?;
        if let Some(store) = made.get(&key) {
            return Ok(Arc::clone(store));
        }
        let store = self.make(url)?;
        made.insert(key, Arc::clone(&store));
        Ok(store)
    }

    fn client_options(&self, allow_http: bool) -> ClientOptions {
        ClientOptions::new()
            .with_allow_http(allow_http)
            .with_connect_timeout(self.limits.connect_timeout)
            .with_read_timeout(self.limits.read_timeout)
            // The whole request, body included, may take long for a large mesh on a slow link;
            // the read time-out catches a stalled one, the item time-out bounds the rest.
            .with_timeout(Duration::from_secs(24 * 3600))
    }

    fn retry(&self) -> RetryConfig {
        RetryConfig {
            backoff: BackoffConfig {
                init_backoff: self.limits.initial_backoff,
                max_backoff: self.limits.max_backoff,
                // object_store draws each wait uniformly between the first backoff and `base`
                // times the previous wait (object_store 0.14, src/client/backoff.rs): base 4
                // doubles the wait on average; base 2 lengthened it by 0.1 s a retry, so that
                // five retries ended 1.5-3.5 s after the first attempt.
                base: 4.0,
            },
            // Both end the retries (object_store's `RetryContext::exhausted`); the time is the
            // limit that holds by default (FetchLimits::retries).
            max_retries: self.limits.retries,
            retry_timeout: self.limits.retry_for,
        }
    }

    fn make(&self, url: &RemoteUrl) -> Result<Arc<dyn ObjectStore>, FetchError> {
        let bucket = url.bucket();
        let failed = |e: object_store::Error| {
            FetchError::new(
                url.to_string(),
                FetchErrorKind::Credentials,
                format!(
                    "cannot set up the {} client: {e} (docs/CLUSTER.md, \"Remote sources\")",
                    url.scheme.as_str()
                ),
            )
        };
        let store: Arc<dyn ObjectStore> = match url.scheme {
            Scheme::Http | Scheme::Https => {
                return Err(FetchError::new(
                    url.to_string(),
                    FetchErrorKind::Location,
                    "an HTTP server is not a bucket: it cannot be listed or hold a job (its \
                     objects are fetched one by one)",
                ))
            }
            Scheme::S3 => {
                let mut builder = AmazonS3Builder::from_env();
                for (key, value) in crate::aws_profile::credentials() {
                    if let Ok(k) = key.parse::<AmazonS3ConfigKey>() {
                        builder = builder.with_config(k, value);
                    }
                }
                let built = builder
                    .with_bucket_name(&bucket)
                    .with_client_options(self.client_options(allow_http("AWS")))
                    .with_retry(self.retry())
                    .build();
                Arc::new(built.map_err(failed)?)
            }
            Scheme::Gs => {
                let built = GoogleCloudStorageBuilder::from_env()
                    .with_bucket_name(&bucket)
                    .with_client_options(self.client_options(allow_http("GOOGLE")))
                    .with_retry(self.retry())
                    .build();
                Arc::new(built.map_err(failed)?)
            }
            Scheme::Az => {
                let built = MicrosoftAzureBuilder::from_env()
                    .with_container_name(&bucket)
                    .with_client_options(self.client_options(allow_http("AZURE")))
                    .with_retry(self.retry())
                    .build();
                Arc::new(built.map_err(failed)?)
            }
        };
        Ok(store)
    }
}

/// Whether a cloud's endpoint may be plain HTTP: `{PREFIX}_ALLOW_HTTP=true`, or an endpoint
/// override (`AWS_ENDPOINT_URL`, `AWS_ENDPOINT`, `AZURE_STORAGE_ENDPOINT`, ...) that is one.
fn allow_http(prefix: &str) -> bool {
    let truthy = |v: String| matches!(v.trim().to_ascii_lowercase().as_str(), "true" | "1");
    if std::env::var(format!("{prefix}_ALLOW_HTTP")).is_ok_and(truthy) {
        return true;
    }
    std::env::vars().any(|(k, v)| {
        k.starts_with(prefix) && k.contains("ENDPOINT") && v.trim().starts_with("http://")
    })
}
