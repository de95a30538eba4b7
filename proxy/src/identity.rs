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

/// Most combining marks kept on one character of a display name: enough for every script's
/// diacritics (Vietnamese stacks two), not for a "Zalgo" flood that covers the lines around it.
pub const MAX_MARKS_PER_CHAR: usize = 3;

/// A display name as the proxy stores and shows it: everything a name cannot carry removed
/// (docs/reliability.md, "Names"), trimmed; `None` when nothing is left. Removed are control
/// characters (C0, C1, DEL: line breaks and escapes), bidirectional controls (embeddings,
/// overrides, isolates, marks: they reorder what follows on the page), zero-width spaces, line
/// and paragraph separators, combining marks past [`MAX_MARKS_PER_CHAR`] on one character, and
/// a trailing `(you)`, which the page writes after one's own name: a peer named "Bob (you)"
/// would pass for oneself. A NUL byte and a length past the limit are refused before
/// (`check_text`), as for any text.
pub fn clean_name(name: &str) -> Option<String> {
    let mut out = String::with_capacity(name.len());
    let mut marks = 0;
    for c in name.chars() {
        if c.is_control() || is_invisible_format(c) {
            continue;
        }
        if unicode_normalization::char::is_combining_mark(c) {
            marks += 1;
            if marks > MAX_MARKS_PER_CHAR {
                continue;
            }
        } else {
            marks = 0;
        }
        out.push(c);
    }
    let mut name = out.trim();
    // "Bob (you)", "Bob(YOU) (you)": each trailing one.
    while let Some(head) = strip_suffix_ignore_case(name, "(you)") {
        name = head.trim_end();
    }
    (!name.is_empty()).then(|| name.to_string())
}

/// Bidirectional controls, zero-width spaces and joiners other than ZWJ (which emoji
/// sequences need), the byte-order mark, line and paragraph separators.
fn is_invisible_format(c: char) -> bool {
    matches!(c,
        '\u{061C}' | '\u{200B}' | '\u{200E}' | '\u{200F}' | '\u{2028}'..='\u{202E}'
        | '\u{2060}'..='\u{2064}' | '\u{2066}'..='\u{2069}' | '\u{FEFF}')
}

fn strip_suffix_ignore_case<'a>(text: &'a str, suffix: &str) -> Option<&'a str> {
    let at = text.len().checked_sub(suffix.len())?;
    let tail = text.get(at..)?;
    tail.eq_ignore_ascii_case(suffix).then(|| &text[..at])
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

    #[test]
    fn a_name_is_cleaned_of_what_it_cannot_carry() {
        assert_eq!(clean_name("  Ada  ").as_deref(), Some("Ada"));
        assert_eq!(clean_name("A\nd\u{1b}[31ma\u{7f}").as_deref(), Some("Ad[31ma"));
        // A right-to-left override would show "Bob" as "boB" and turn what follows around.
        assert_eq!(clean_name("\u{202E}boB\u{202C} \u{2066}x\u{2069}").as_deref(), Some("boB x"));
        let zalgo = format!("Z{}a", "\u{0301}".repeat(40));
        assert_eq!(clean_name(&zalgo), Some(format!("Z{}a", "\u{0301}".repeat(3))));
        // Real diacritics stay: Vietnamese stacks two marks, decomposed.
        assert_eq!(clean_name("Vie\u{0323}\u{0302}t").as_deref(), Some("Vie\u{0323}\u{0302}t"));
        assert_eq!(clean_name("Bob (you)").as_deref(), Some("Bob"));
        assert_eq!(clean_name("Bob(YOU) (You) ").as_deref(), Some("Bob"));
        assert_eq!(clean_name("you").as_deref(), Some("you"));
        assert_eq!(clean_name("👩\u{200D}💻 Ada").as_deref(), Some("👩\u{200D}💻 Ada"));
        assert_eq!(clean_name("\u{200B}\u{202E} (you)"), None);
        assert_eq!(clean_name("(you)"), None);
    }
}
