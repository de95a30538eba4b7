//! Display names: a participant renames itself, the others present hear it (on the other
//! replica too, with PostgreSQL), and a newcomer's history has the new name.

use penmesh::protocol::{ClientMessage, ErrorCode, Rename, ServerMessage};

use crate::helpers::{Participant, one_or_two_replicas};

#[tokio::test]
async fn a_new_name_reaches_everyone_present_and_every_newcomer() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut ada = Participant::join(a, &session, "guest 1f2e").await;
    let mut other = Participant::join(b, &session, "other").await;
    let me = ada.welcome.participant;
    other.wait_for(|v| v.present.get(&me).is_some_and(|n| n == "guest 1f2e")).await;

    ada.ws.send(&ClientMessage::Rename(Rename { name: "  Ada  ".into() })).await;
    other.wait_for(|v| v.present.get(&me).is_some_and(|n| n == "Ada")).await;
    let late = Participant::join(b, &session, "late").await;
    assert_eq!(late.view.present[&me], "Ada");

    // A name with a NUL byte is refused, naming the field; nothing changes.
    ada.ws.send(&ClientMessage::Rename(Rename { name: "A\0da".into() })).await;
    let err = ada.ws.expect_error(ErrorCode::Malformed).await;
    assert!(err.message.contains("rename.name"), "{}", err.message);
    ada.ws.send(&ClientMessage::Rename(Rename { name: "Ada L.".into() })).await;
    match other.recv_until(|m| matches!(m, ServerMessage::PeerRenamed(_))).await {
        ServerMessage::PeerRenamed(r) => {
            assert_eq!((r.participant, r.name.as_str()), (me, "Ada L."))
        }
        _ => unreachable!(),
    }
}

/// A name is cleaned of what would mislead or deface the others' pages: control characters,
/// bidirectional overrides, floods of combining marks, and a trailing "(you)", which the page
/// writes after one's own name. Before, each was stored and shown as sent.
#[tokio::test]
async fn a_name_is_cleaned_of_what_would_mislead_the_others() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut other = Participant::join(b, &session, "other").await;
    let mallory = Participant::join(a, &session, "\u{202E}Bob\u{202C} (you)").await;
    let me = mallory.welcome.participant;
    other.wait_for(|v| v.present.get(&me).is_some_and(|n| n == "Bob")).await;

    let mut mallory = mallory;
    let zalgo = format!("E{}ve\r\n\u{1b}[2J", "\u{0336}".repeat(60));
    mallory.ws.send(&ClientMessage::Rename(Rename { name: zalgo })).await;
    let cleaned = format!("E{}ve[2J", "\u{0336}".repeat(3));
    other.wait_for(|v| v.present.get(&me) == Some(&cleaned)).await;
    // Nothing left once cleaned: refused, naming why.
    mallory.ws.send(&ClientMessage::Rename(Rename { name: "\u{2066} (You)".into() })).await;
    let err = mallory.ws.expect_error(ErrorCode::Malformed).await;
    assert!(err.message.contains("empty once cleaned"), "{}", err.message);
    let late = Participant::join(b, &session, "late").await;
    assert_eq!(late.view.present[&me], cleaned);
}

/// Renames are held to one a second per connection: 30 sent at once reach the others as the
/// first and the last (the latest waiting its turn replaces the ones before it), not as 30
/// commits and 30 messages to every viewer.
#[tokio::test]
async fn renames_are_held_to_one_a_second_and_the_last_one_wins() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut other = Participant::join(b, &session, "other").await;
    let mut ada = Participant::join(a, &session, "ada").await;
    let me = ada.welcome.participant;
    other.wait_for(|v| v.present.contains_key(&me)).await;
    let started = std::time::Instant::now();
    for k in 0..30 {
        ada.ws.send(&ClientMessage::Rename(Rename { name: format!("name {k}") })).await;
    }
    let mut heard = Vec::new();
    while heard.last().map(String::as_str) != Some("name 29") {
        if let ServerMessage::PeerRenamed(r) =
            other.recv_until(|m| matches!(m, ServerMessage::PeerRenamed(_))).await
        {
            heard.push(r.name);
        }
    }
    assert_eq!(heard, ["name 0", "name 29"], "every rename was stored and sent");
    assert!(started.elapsed() >= std::time::Duration::from_millis(900), "the last came early");
    let late = Participant::join(b, &session, "late").await;
    assert_eq!(late.view.present[&me], "name 29");
}
