//! TLS: reqwest is built with rustls and no crypto provider chosen (so that aws-lc-sys, a C
//! library with a long build, is not compiled); ring's provider is installed as the process
//! default before the first client is made.

use std::sync::Once;

/// Installs ring as rustls' process-wide crypto provider, once. Another provider already
/// installed (by whoever embeds us) is left in place.
pub(crate) fn install_provider() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = rustls::crypto::ring::default_provider().install_default();
    });
}
