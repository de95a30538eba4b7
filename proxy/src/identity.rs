//! Who a participant is: the proxy derives the id from the session and the participant's
//! secret key (`Hello.key`, or the `x-penmesh-key` header over HTTP), so the same key is the
//! same participant on every connection and replica, and no table holds the key. Only a
//! stroke's participant may resume it, append to it, or store or build its mesh
//! (docs/reliability.md, "Who may do what").

use penmesh::protocol::{KEY_HEADER, ParticipantId, check_participant_key};
use sha2::Digest;
use uuid::Uuid;

/// The participant whose key is `key` in `session`. A UUID of version 8 (custom): the first
/// 16 bytes of SHA-256 over a label, the session and the key; so it can never equal the
/// random (version 4) identity of a connection without a key.
pub fn participant_id(session: Uuid, key: &str) -> ParticipantId {
    let digest = sha2::Sha256::new_with_prefix(b"penmesh participant\0")
        .chain_update(session.as_bytes())
        .chain_update(key.as_bytes())
        .finalize();
    let mut bytes = [0u8; 16];
    bytes.copy_from_slice(&digest[..16]);
    uuid::Builder::from_custom_bytes(bytes).into_uuid()
}

/// Why a request or a hello's key is refused.
#[derive(Debug, Clone, PartialEq)]
pub enum KeyError {
    Missing,
    /// The message names the field.
    Malformed(String),
}

/// The participant of a key given in `field` (`hello.key`, or the header), checked for form;
/// the error names the field.
pub fn participant_of(session: Uuid, field: &str, key: &str) -> Result<ParticipantId, String> {
    check_participant_key(key).map_err(|why| format!("{field} {why}"))?;
    Ok(participant_id(session, key))
}

/// The participant an HTTP request speaks for: its [`KEY_HEADER`].
pub fn request_participant(
    session: Uuid,
    headers: &axum::http::HeaderMap,
) -> Result<ParticipantId, KeyError> {
    let value = headers.get(KEY_HEADER).ok_or(KeyError::Missing)?;
    let key = value.to_str().map_err(|_| {
        KeyError::Malformed(format!("{KEY_HEADER} holds characters a participant key cannot"))
    })?;
    participant_of(session, KEY_HEADER, key).map_err(KeyError::Malformed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_key_is_the_same_participant_only_within_a_session() {
        let (a, b) = (Uuid::new_v4(), Uuid::new_v4());
        let key = "0123456789abcdef0123456789abcdef";
        assert_eq!(participant_id(a, key), participant_id(a, key));
        assert_ne!(participant_id(a, key), participant_id(b, key));
        assert_ne!(participant_id(a, key), participant_id(a, "0123456789abcdef0123456789abcdeF"));
        assert_eq!(participant_id(a, key).get_version_num(), 8);
    }

    #[test]
    fn a_malformed_key_is_refused_naming_the_field() {
        let message = participant_of(Uuid::nil(), "hello.key", "short").unwrap_err();
        assert!(message.starts_with("hello.key is 5 characters"), "{message}");
    }
}
