//! Placements across replicas in the hard cases (issue 37): the same stroke placed at the same
//! moment through both replicas, and a rolling deploy in which a replica of the previous release
//! (whose `NOTIFY` payloads are of version 5) places a stroke, once and then at every commit.
//! PostgreSQL only: these need two replicas, or a notification that only PostgreSQL carries.

use penmesh::Placement;
use penmesh::protocol::{ClientMessage, ServerMessage, SetPlacement, StrokeId};
use penmesh_e2e::{TestDatabase, TestSession, count_rows, execute_sql};
use uuid::Uuid;

use crate::helpers::{Participant, two_replicas};
use crate::placement::{bits, draw_on, history, listed, matrix_body, put_placement, standing};

/// Distinct placements, one per change: the board turned by `k` degrees about the world's z
/// and moved by `k` millimetres, every element a full `f64`.
fn nth(k: usize) -> Placement {
    let (s, c) = (k as f64).to_radians().sin_cos();
    let t = k as f64 + 0.125;
    Placement::new([c, s, 0.0, 0.0, -s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t, -t, 0.5 * t, 1.0])
        .unwrap()
}

/// Reads `p`'s messages until it has seen every participant of `fences` join, and returns the
/// placements of `stroke` it was told meanwhile (live, in an answer, or in a history), in order.
async fn told_until(p: &mut Participant, stroke: StrokeId, fences: &[Uuid]) -> Vec<Placement> {
    let mut told = Vec::new();
    while !fences.iter().all(|f| p.view.present.contains_key(f)) {
        let msg = p.recv().await;
        let messages = match &msg {
            ServerMessage::PeerStrokes(strokes) => strokes.messages(),
            ServerMessage::Error(e) => panic!("unexpected error: {e:?}"),
            _ => vec![msg],
        };
        for msg in messages {
            if let ServerMessage::PeerPlacement(placed) = msg
                && placed.stroke == stroke
            {
                told.push(placed.placement);
            }
        }
    }
    told
}

/// The drawer places one stroke through its connection on each replica and over HTTP on each,
/// all four at the same moment, ten times over. Every change is kept (in the order of its row);
/// the stored placement is the last of them; and every connection (the drawer's two, a watcher
/// on each replica) is told placements only in that order, never an older after a newer, and
/// ends with the stored one, as does a late joiner on each replica.
#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn the_same_stroke_placed_at_once_on_two_replicas_ends_the_same_everywhere() {
    const ROUNDS: usize = 10;
    let (a, b) = two_replicas().await;
    let session = a.create_session().await;
    let mut on_a = Participant::join(&a, &session, "drawer").await;
    let stroke = Uuid::new_v4();
    draw_on(&mut on_a, stroke, 0, standing()).await;
    let mut on_b = Participant::join_resuming(&b, &session, "drawer", &on_a.key, vec![]).await;
    let mut watch_a = Participant::join(&a, &session, "watcher a").await;
    let mut watch_b = Participant::join(&b, &session, "watcher b").await;
    let as_drawer = TestSession { key: on_a.key.clone(), ..session.clone() };

    for round in 0..ROUNDS {
        let [by_a, by_b, http_a, http_b] = [0, 1, 2, 3].map(|i| nth(4 * round + i + 1));
        let set = |placement| ClientMessage::SetPlacement(SetPlacement { stroke, placement });
        let (set_a, set_b) = (set(by_a), set(by_b));
        let (_, _, put_a, put_b) = tokio::join!(
            on_a.ws.send(&set_a),
            on_b.ws.send(&set_b),
            put_placement(&a, &as_drawer, stroke, matrix_body(&http_a)),
            put_placement(&b, &as_drawer, stroke, matrix_body(&http_b)),
        );
        assert_eq!((put_a.0, put_b.0), (204, 204), "{put_a:?} {put_b:?}");
    }

    // Every change committed (the sockets' too) and kept: the begin's, then 4 × ROUNDS.
    let rows = "SELECT COUNT(*) FROM stroke_placements";
    let deadline = tokio::time::Instant::now() + penmesh_e2e::TIMEOUT;
    while count_rows(&a.db, rows).await < 1 + 4 * ROUNDS as i64 {
        assert!(tokio::time::Instant::now() < deadline, "the placements were not all stored");
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    let kept = history(&a, &session, stroke).await;
    assert_eq!(kept.len(), 1 + 4 * ROUNDS, "a change lost");
    assert_eq!(bits(&kept[0].0), bits(&standing()));
    let mut matrices: Vec<Vec<u8>> = kept.iter().map(|(p, _, _)| bits(p)).collect();
    let order = matrices.clone();
    matrices.sort();
    matrices.dedup();
    assert_eq!(matrices.len(), kept.len(), "a change stored twice");
    assert!(kept.iter().all(|(_, by, _)| *by == on_a.welcome.participant));
    let stored = bits(&kept.last().unwrap().0);
    assert_eq!(listed(&a, &session).await, vec![(stroke, stored.clone())]);
    assert_eq!(listed(&b, &session).await, vec![(stroke, stored.clone())]);

    // Fences: a join on each replica, notified after every placement was committed, so each
    // connection has been told all it will be told of the stroke once it has seen both.
    let fence_a = Participant::join(&a, &session, "fence a").await;
    let fence_b = Participant::join(&b, &session, "fence b").await;
    let fences = [fence_a.welcome.participant, fence_b.welcome.participant];
    for (name, p) in [
        ("drawer on a", &mut on_a),
        ("drawer on b", &mut on_b),
        ("a", &mut watch_a),
        ("b", &mut watch_b),
    ] {
        let told = told_until(p, stroke, &fences).await;
        let rows: Vec<usize> = told
            .iter()
            .map(|t| {
                order.iter().position(|m| *m == bits(t)).expect("told a placement never stored")
            })
            .collect();
        assert!(
            rows.windows(2).all(|w| w[0] < w[1]),
            "{name} was told an older placement after a newer one: rows {rows:?}"
        );
        assert_eq!(
            rows.last(),
            Some(&(order.len() - 1)),
            "{name} does not end with the stored placement: rows {rows:?}"
        );
    }
    for proxy in [&a, &b] {
        let late = Participant::join(proxy, &session, "late").await;
        let told = late.view.strokes[&stroke].placement.map(|p| bits(&p));
        assert_eq!(told, Some(stored.clone()), "a late joiner");
    }
}

/// What a replica of the previous release does when `by` places `stroke`, as its writer does it:
/// the row, then the notification in version 5 (whose `placed` has no row id).
async fn place_as_the_previous_release(
    db: &TestDatabase,
    session: Uuid,
    (stroke, by): (StrokeId, Uuid),
    placement: &Placement,
    at: usize,
) {
    let matrix = hex::encode(placement.to_bytes());
    execute_sql(
        db,
        &format!(
            "INSERT INTO stroke_placements (stroke_id, matrix, set_by, set_at, cause) \
             VALUES ('{stroke}', decode('{matrix}', 'hex'), '{by}', {at}, 'set')"
        ),
    )
    .await;
    let payload = serde_json::json!({ "v": 5, "events": [{
        "session": session, "event": "placed", "participant": by, "stroke": stroke,
        "placement": { "matrix": placement.matrix() },
    }]});
    execute_sql(db, &format!("SELECT pg_notify('penmesh_events', '{payload}')")).await;
}

/// A rolling deploy: a replica of the previous release stores a placement and notifies it as
/// version 5 (without the row's id). This release cannot read that payload, so it resyncs its
/// connections from the database, and its watcher ends with the stored placement.
#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn a_placement_notified_by_a_replica_of_the_previous_release_reaches_watchers_by_a_resync() {
    let (a, b) = two_replicas().await;
    let session = a.create_session().await;
    let mut drawer = Participant::join(&a, &session, "drawer").await;
    let stroke = Uuid::new_v4();
    draw_on(&mut drawer, stroke, 0, standing()).await;
    let mut watcher = Participant::join(&b, &session, "watcher").await;
    assert_eq!(watcher.view.strokes[&stroke].placement.map(|p| bits(&p)), Some(bits(&standing())));

    let moved = nth(33);
    let by = drawer.welcome.participant;
    place_as_the_previous_release(&a.db, session.session, (stroke, by), &moved, 1).await;

    watcher.wait_for(|v| v.n_synced >= 2).await;
    assert_eq!(watcher.view.strokes[&stroke].placement.map(|p| bits(&p)), Some(bits(&moved)));
    assert_eq!(watcher.view.n_lagged, 0, "a gap, not a lag");
    assert_eq!(listed(&b, &session).await, vec![(stroke, bits(&moved))]);
}

/// A rolling deploy, as it goes on: the replica of the previous release notifies every commit
/// (here 100 payloads in about 3 s). Each is unreadable here; resyncing every connection
/// for each would read every watcher's whole history from the database over and over while
/// the deploy lasts. The resyncs are coalesced (at most one a second, the last after the last
/// payload), and the watcher still ends with what is stored.
#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn a_stream_of_unreadable_payloads_resyncs_a_watcher_once_a_second_not_once_each() {
    let (a, b) = two_replicas().await;
    let session = a.create_session().await;
    let mut drawer = Participant::join(&a, &session, "drawer").await;
    let stroke = Uuid::new_v4();
    draw_on(&mut drawer, stroke, 0, standing()).await;
    let mut watcher = Participant::join(&b, &session, "watcher").await;

    let by = drawer.welcome.participant;
    let started = tokio::time::Instant::now();
    let mut last = standing();
    for k in 0..100 {
        last = nth(100 + k);
        place_as_the_previous_release(&a.db, session.session, (stroke, by), &last, k).await;
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    let sent_for = started.elapsed();
    watcher
        .wait_for(|v| v.strokes[&stroke].placement.is_some_and(|p| bits(&p) == bits(&last)))
        .await;
    let resyncs = watcher.view.n_synced - 1;
    // At most one a second while they come, one after the last, and one for the delay of the
    // notifications on their way.
    let most = 3 + sent_for.as_secs() as usize;
    assert!(
        (1..=most).contains(&resyncs),
        "{resyncs} resyncs for 100 unreadable payloads in {sent_for:?} (at most {most})"
    );
    assert_eq!(watcher.view.n_lagged, 0);
}
