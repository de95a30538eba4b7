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
