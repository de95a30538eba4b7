//! Where the proxy is and which session to draw in: the server URL checked and normalised.

use uuid::Uuid;

/// Where the proxy is and which session to draw in.
#[derive(Debug, Clone)]
pub struct Endpoint {
    /// `http://HOST:PORT` (a `ws://` URL is accepted and turned into this).
    pub base: String,
    pub session: Uuid,
    pub token: String,
}

impl Endpoint {
    /// Checks and normalises the server URL.
    pub fn new(server: &str, session: Uuid, token: String) -> anyhow::Result<Endpoint> {
        let server = server.trim().trim_end_matches('/');
        let base = if let Some(rest) = server.strip_prefix("ws://") {
            format!("http://{rest}")
        } else if server.starts_with("http://") {
            server.to_string()
        } else if server.starts_with("https://") || server.starts_with("wss://") {
            anyhow::bail!(
                "{server}: TLS is not built into this client; put the proxy behind plain http:// (e.g. a local TLS-terminating tunnel)"
            );
        } else {
            anyhow::bail!("{server}: the server URL must start with http:// or ws://");
        };
        anyhow::ensure!(!token.trim().is_empty(), "the session token is empty");
        Ok(Endpoint { base, session, token })
    }

    pub fn ws_url(&self) -> String {
        let rest = self.base.strip_prefix("http://").unwrap_or(&self.base);
        format!("ws://{rest}{}", crate::api::session_ws(self.session))
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn server_urls_are_normalised_and_tls_is_refused_clearly() {
        let session = Uuid::nil();
        let e = Endpoint::new("ws://127.0.0.1:8080/", session, "t".into()).unwrap();
        assert_eq!(e.base, "http://127.0.0.1:8080");
        assert_eq!(e.ws_url(), format!("ws://127.0.0.1:8080/v1/sessions/{session}/ws"));
        assert!(
            Endpoint::new("https://x", session, "t".into())
                .unwrap_err()
                .to_string()
                .contains("TLS")
        );
        assert!(Endpoint::new("localhost:1", session, "t".into()).is_err());
    }
}
