//! Fetching one `http(s)://` object whole, with reqwest directly. object_store's HTTP store
//! (used before) needs a Content-Length, so a chunked or close-delimited body (common from
//! dynamic servers and CDNs) always failed; it passed a gzip-encoded body on as the object;
//! and it took a `206 Partial Content` to a plain GET for the whole object. Here:
//!
//! - the body is read as it streams and capped by the bytes read; a Content-Length, when the
//!   server gives one, refuses an object over the cap before the body is read and is checked
//!   against the bytes that came (fewer: truncated);
//! - the request accepts `gzip`; a `Content-Encoding: gzip` body is decoded (capped by its
//!   decoded size), and any other coding is refused by name;
//! - only `200 OK` is the object: a `206` to a request for no range is refused, 404 and 410
//!   are "not found", 401 and 403 credentials, 408, 429 and 5xx are retried;
//! - connection errors, time-outs and bodies that break off are retried, as [`Backoff`]
//!   allows (the whole object again).

use crate::error::{FetchError, FetchErrorKind};
use crate::fetched::{too_large, Fetched, PREALLOCATE_AT_MOST};
use crate::limits::{Backoff, FetchLimits};
use crate::location::RemoteUrl;
use reqwest::header::{HeaderMap, ACCEPT_ENCODING, CONTENT_ENCODING, CONTENT_LENGTH};
use reqwest::StatusCode;
use sha2::{Digest, Sha256};
use std::io::Read;

/// A failed attempt, and whether another one may succeed.
struct Failed {
    error: FetchError,
    retry: bool,
}

impl Failed {
    fn new(url: &str, kind: FetchErrorKind, message: String, retry: bool) -> Self {
        Self {
            error: FetchError::new(url, kind, message),
            retry,
        }
    }

    fn fatal(error: FetchError) -> Self {
        Self {
            error,
            retry: false,
        }
    }
}

/// How the body is encoded (`Content-Encoding`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Coding {
    Identity,
    Gzip,
}

/// The client every `http(s)://` fetch of the process shares (its connections are kept
/// across items), with the limits' connect and read time-outs.
pub(crate) fn client(limits: &FetchLimits) -> Result<reqwest::Client, FetchError> {
    reqwest::Client::builder()
        .connect_timeout(limits.connect_timeout)
        .read_timeout(limits.read_timeout)
        .build()
        .map_err(|e| {
            FetchError::new(
                "",
                FetchErrorKind::Other,
                format!("cannot set up the HTTP client: {e}"),
            )
        })
}

/// The object at `url`, whole, retried as [`Backoff`] allows.
pub(crate) async fn get(
    client: &reqwest::Client,
    url: &RemoteUrl,
    limits: &FetchLimits,
) -> Result<Fetched, FetchError> {
    let mut backoff = Backoff::new(limits);
    loop {
        let failed = match attempt(client, url, limits.max_bytes).await {
            Ok(fetched) => return Ok(fetched),
            Err(failed) => failed,
        };
        if !failed.retry {
            return Err(failed.error);
        }
        match backoff.next_wait() {
            Some(wait) => tokio::time::sleep(wait).await,
            None => {
                let mut error = failed.error;
                error.message = format!("{} ({})", error.message, backoff.said());
                return Err(error);
            }
        }
    }
}

async fn attempt(client: &reqwest::Client, url: &RemoteUrl, cap: u64) -> Result<Fetched, Failed> {
    let name = url.to_string();
    let response = client
        .get(name.as_str())
        .header(ACCEPT_ENCODING, "gzip")
        .send()
        .await
        .map_err(|e| transport(&name, &e, "no answer"))?;
    check_status(&name, response.status())?;
    let coding = coding(&name, response.headers())?;
    let announced = content_length(response.headers());
    if let Some(size) = announced.filter(|&n| n > cap && coding == Coding::Identity) {
        return Err(Failed::fatal(too_large(url, size.to_string(), cap)));
    }
    let body = read_body(url, response, announced, cap).await?;
    let bytes = match coding {
        Coding::Identity => body,
        Coding::Gzip => gunzip(url, &body, cap)?,
    };
    let sha256 = format!("{:x}", Sha256::digest(&bytes));
    Ok(Fetched { bytes, sha256 })
}

/// A failed request or body read: a time-out, a connection that could not be opened or that
/// broke, said with `what` (where it failed); each may succeed at the next attempt.
fn transport(url: &str, e: &reqwest::Error, what: &str) -> Failed {
    let mut text = e.to_string();
    let mut source = std::error::Error::source(e);
    while let Some(s) = source {
        text = format!("{text}: {s}");
        source = s.source();
    }
    let kind = if e.is_timeout() {
        FetchErrorKind::Timeout
    } else {
        FetchErrorKind::Other
    };
    let why = if e.is_timeout() {
        format!("{what}: timed out ({text})")
    } else {
        format!("{what}: {text}")
    };
    Failed::new(url, kind, why, true)
}

/// Only `200 OK` is the object.
fn check_status(url: &str, status: StatusCode) -> Result<(), Failed> {
    if status == StatusCode::OK {
        return Ok(());
    }
    let said = format!("the server answered {status}");
    Err(match status.as_u16() {
        206 => Failed::new(
            url,
            FetchErrorKind::Other,
            format!(
                "{said} to a request for the whole object: a part of it, which is never taken \
                 for the whole (a server or cache that answers ranges unasked)"
            ),
            false,
        ),
        404 | 410 => Failed::new(
            url,
            FetchErrorKind::NotFound,
            format!("not found ({said})"),
            false,
        ),
        401 | 403 => Failed::new(
            url,
            FetchErrorKind::Credentials,
            format!("{said}: sparc3d sends no credentials to HTTP servers"),
            false,
        ),
        408 | 429 | 500..=599 => Failed::new(url, FetchErrorKind::Other, said, true),
        _ => Failed::new(url, FetchErrorKind::Other, said, false),
    })
}

/// The body's coding: identity or gzip; any other is refused by name.
fn coding(url: &str, headers: &HeaderMap) -> Result<Coding, Failed> {
    let mut coding = Coding::Identity;
    for value in headers.get_all(CONTENT_ENCODING) {
        let text = String::from_utf8_lossy(value.as_bytes()).to_ascii_lowercase();
        for name in text.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match (name, coding) {
                ("identity", _) => {}
                ("gzip" | "x-gzip", Coding::Identity) => coding = Coding::Gzip,
                _ => {
                    return Err(Failed::new(
                        url,
                        FetchErrorKind::Other,
                        format!(
                            "the server sent the body with Content-Encoding {text:?}, which \
                             sparc3d does not decode (it asks for gzip or none; serve the file \
                             as it is)"
                        ),
                        false,
                    ))
                }
            }
        }
    }
    Ok(coding)
}

fn content_length(headers: &HeaderMap) -> Option<u64> {
    let value = headers.get(CONTENT_LENGTH)?;
    value.to_str().ok()?.trim().parse().ok()
}

/// The body as it came, at most `cap` bytes; with a Content-Length, exactly that many.
/// Without one its chunks are kept as they came and joined once it ends, so that a body
/// that never ends holds about `cap` bytes when it is refused (issue 64 item 8: a growing
/// buffer doubled past the item's memory limit and the item died as `out_of_memory` before
/// the cap said `too_large`).
async fn read_body(
    url: &RemoteUrl,
    mut response: reqwest::Response,
    announced: Option<u64>,
    cap: u64,
) -> Result<Vec<u8>, Failed> {
    let name = url.to_string();
    let reserve = announced.unwrap_or(0).min(cap).min(PREALLOCATE_AT_MOST);
    let mut bytes = Vec::with_capacity(reserve as usize);
    let mut chunks = Vec::new();
    let mut len = 0u64;
    let of = announced.map_or(String::new(), |n| format!(" of {n}"));
    loop {
        let chunk = response.chunk().await.map_err(|e| {
            let where_ = format!("the body broke off after {len}{of} bytes");
            let mut failed = transport(&name, &e, &where_);
            if failed.error.kind == FetchErrorKind::Other {
                failed.error.kind = FetchErrorKind::Truncated;
            }
            failed
        })?;
        let Some(chunk) = chunk else { break };
        len += chunk.len() as u64;
        if len > cap {
            return Err(Failed::fatal(too_large(
                url,
                format!("more than {cap}"),
                cap,
            )));
        }
        match announced {
            Some(_) => bytes.extend_from_slice(&chunk),
            None => chunks.push(chunk),
        }
    }
    if announced.is_none() {
        bytes = Vec::with_capacity(len as usize);
        for chunk in chunks {
            bytes.extend_from_slice(&chunk);
        }
    }
    match announced {
        Some(size) if size != bytes.len() as u64 => Err(Failed::new(
            &name,
            FetchErrorKind::Truncated,
            format!(
                "the body has {} bytes, the server announced {size} (truncated)",
                bytes.len()
            ),
            true,
        )),
        _ => Ok(bytes),
    }
}

/// A gzip body decoded, at most `cap` bytes of it.
fn gunzip(url: &RemoteUrl, body: &[u8], cap: u64) -> Result<Vec<u8>, Failed> {
    let mut out = Vec::new();
    let decoder = flate2::read::MultiGzDecoder::new(body);
    decoder
        .take(cap.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| {
            Failed::new(
                &url.to_string(),
                FetchErrorKind::Other,
                format!(
                    "the body is sent gzip-encoded (Content-Encoding: gzip) but does not \
                     decode: {e}"
                ),
                true,
            )
        })?;
    if out.len() as u64 > cap {
        return Err(Failed::fatal(too_large(
            url,
            format!("more than {cap}"),
            cap,
        )));
    }
    Ok(out)
}
