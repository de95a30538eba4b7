//! Strokes taken back and brought back, seen by connections that were not there or not
//! listening when it happened: a late joiner, who never had a stroke taken back before it came,
//! hears of that stroke's mesh uploads nothing and gets it whole when it is brought back, with
//! no resync (issue 35's first defect, issue 38's sixth point); a watcher that fell behind
//! (`lagged`) or lost events (a PostgreSQL listener gap) ends with exactly the stored state,
//! placements included.

use penmesh::Placement;
use penmesh::protocol::{ServerMessage, StrokeId};
use penmesh_e2e::{
    TestDatabase, TestSession, batch_simplified, execute_sql, minimal_glb, spawn_proxy_with,
};
use uuid::Uuid;

use crate::helpers::{Participant, View, one_or_two_replicas, put_mesh, samples_for};
use crate::placement::{bits, draw_on, matrix_body, put_placement, standing};
use crate::removal::http_removal;
use crate::slow_reader::{join_slow_reader, next_message};

/// 30 mesh uploads for a stroke taken back before two watchers joined reach neither (no
/// second `Synced`: no resync of the whole history); brought back, the stroke reaches them
/// whole, with its mesh, still without a resync. Before, every upload made every late watcher
/// re-read the session, and the restore did too.
#[tokio::test]
async fn a_stroke_taken_back_before_a_watcher_came_costs_it_no_resync() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let (kept, taken) = (Uuid::new_v4(), Uuid::new_v4());
    drawer.draw(kept, &samples_for(0, 40), 10).await;
    drawer.draw(taken, &samples_for(1, 40), 10).await;
    assert_eq!(http_removal(a, &as_drawer, taken, true).await, 204);

    let mut late = [
        Participant::join(b, &session, "late 1").await,
        Participant::join(a, &session, "late 2").await,
    ];
    for watcher in &late {
        assert!(
            !watcher.view.strokes.contains_key(&taken),
            "a stroke taken back is in the history"
        );
    }
    for _ in 0..30 {
        let response = a.put_mesh(&as_drawer, taken, minimal_glb(3, 3)).send().await.unwrap();
        assert_eq!(response.status(), 200, "a mesh for a stroke taken back is stored");
    }
    // A stroke drawn after the uploads: once the watchers have it, they have had the uploads'
    // events (one replica's commits reach its listeners in order).
    let marker = Uuid::new_v4();
    drawer.draw(marker, &samples_for(2, 40), 10).await;
    for watcher in &mut late {
        watcher.wait_for(|v| v.strokes.get(&marker).is_some_and(|s| s.done)).await;
        assert_eq!(watcher.view.n_synced, 1, "a late watcher resynced for a stroke it never had");
        assert!(!watcher.view.strokes.contains_key(&taken));
    }

    // Brought back: each late watcher gets it whole (samples, done, its mesh) as a history's
    // stroke comes, and nothing else.
    assert_eq!(http_removal(b, &as_drawer, taken, false).await, 204);
    for watcher in &mut late {
        let msg = watcher.recv_until(|m| matches!(m, ServerMessage::PeerStrokes(_))).await;
        let ServerMessage::PeerStrokes(strokes) = msg else { unreachable!() };
        assert_eq!(strokes.strokes.len(), 1);
        let seen = &watcher.view.strokes[&taken];
        assert_eq!(seen.retained, batch_simplified(&samples_for(1, 40)));
        assert!(seen.done && !seen.removed);
        assert_eq!(seen.meshes, 1, "the latest mesh, once");
        assert_eq!(watcher.view.n_synced, 1, "a restore made a late watcher resync");
    }
    // Live from there on: a new mesh reaches them as any does.
    put_mesh(a, &drawer, &session, taken).await;
    for watcher in &mut late {
        watcher.wait_for(|v| v.strokes[&taken].meshes == 2).await;
        assert_eq!(watcher.view.n_synced, 1);
    }
}

const QUEUE: usize = 64;

/// A watcher that falls behind (`lagged`) while one stroke it shows is taken back and another
/// it shows taken back is brought back: the resync tells it both, so its page ends with exactly
/// the stored state. Before, it got the strokes it lacked and nothing about those it had.
#[tokio::test]
async fn a_lagged_watcher_is_told_of_the_removals_and_restores_it_missed() {
    let proxy = spawn_proxy_with(|c| c.outgoing_queue = QUEUE).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let (to_server, mut from_server, slow) = join_slow_reader(&proxy, &session).await;
    let (first, second) = (Uuid::new_v4(), Uuid::new_v4());
    drawer.draw(first, &samples_for(0, 40), 10).await;
    drawer.draw(second, &samples_for(1, 40), 10).await;
    assert_eq!(http_removal(&proxy, &as_drawer, second, true).await, 204);
    // Far more events than the watcher's queues hold: it lags.
    for k in 0..20 {
        drawer.draw(Uuid::new_v4(), &samples_for(k + 2, 200), 4).await;
    }
    // While it is cut off: the first taken back, the second brought back.
    assert_eq!(http_removal(&proxy, &as_drawer, first, true).await, 204);
    assert_eq!(http_removal(&proxy, &as_drawer, second, false).await, 204);

    let mut view = View::default();
    // Its first `Synced`, then one after each `lagged` (the history read once it reads again).
    while view.n_lagged == 0 || view.n_synced < 1 + view.n_lagged || view.n_done() < 22 {
        view.apply(&next_message(&mut from_server).await);
    }
    assert!(view.n_lagged >= 1, "the watcher did not lag");
    assert_eq!(view.n_done(), 22);
    assert!(view.strokes[&first].removed, "a stroke taken back while it lagged stays shown");
    assert!(!view.strokes[&second].removed, "a stroke brought back while it lagged stays hidden");
    drop(to_server);
    let _ = tokio::time::timeout(penmesh_e2e::TIMEOUT, slow).await;
}

/// A watcher told a stroke's standing plane, then cut off (`lagged`) while the stroke is put
/// back on the board: the resync tells it the board. Before, a history left out every current
/// placement that is the board (the default), so the watcher kept showing the standing plane.
#[tokio::test]
async fn a_lagged_watcher_is_told_a_stroke_put_back_on_the_board() {
    let proxy = spawn_proxy_with(|c| c.outgoing_queue = QUEUE).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let (to_server, mut from_server, slow) = join_slow_reader(&proxy, &session).await;
    let mut view = View::default();
    let stroke = Uuid::new_v4();
    draw_on(&mut drawer, stroke, 0, standing()).await;
    let placed =
        |view: &View| view.strokes.get(&stroke).and_then(|s| s.placement).map(|p| bits(&p));
    while placed(&view) != Some(bits(&standing())) {
        view.apply(&next_message(&mut from_server).await);
    }
    // Far more events than the watcher's queues hold: it lags. Meanwhile, back on the board.
    for k in 0..20 {
        drawer.draw(Uuid::new_v4(), &samples_for(k + 2, 200), 4).await;
    }
    let board = matrix_body(&Placement::IDENTITY);
    assert_eq!(put_placement(&proxy, &as_drawer, stroke, board).await.0, 204);
    // The drawer is told of it through the same fan-out, after every event before it (in
    // commit order, through PostgreSQL's notifications too): from then on nothing more comes
    // to the watcher's queue, so the resync's history alone tells it.
    let on_board = |m: &ServerMessage| matches!(m, ServerMessage::PeerPlacement(p) if p.stroke == stroke && p.placement.is_identity());
    drawer.recv_until(on_board).await;

    while view.n_lagged == 0 || view.n_synced < 1 + view.n_lagged || view.n_done() < 21 {
        view.apply(&next_message(&mut from_server).await);
    }
    assert!(view.n_lagged >= 1, "the watcher did not lag");
    assert_eq!(placed(&view), Some(bits(&Placement::IDENTITY)), "still on the standing plane");
    drop(to_server);
    let _ = tokio::time::timeout(penmesh_e2e::TIMEOUT, slow).await;
}

/// Events lost upstream (a PostgreSQL listener that cannot read a notification, as from a
/// replica of another release, resyncs every local connection; on SQLite the same call): a
/// stroke the watcher shows was taken back and another brought back in the database meanwhile.
/// The resync tells it both.
#[tokio::test]
async fn a_watcher_resynced_after_a_listener_gap_ends_with_the_stored_state() {
    let db = TestDatabase::fresh().await;
    let proxy = penmesh_e2e::spawn_proxy_on(db.clone(), |_| {}).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let mut watcher = Participant::join(&proxy, &session, "watcher").await;
    let (first, second) = (Uuid::new_v4(), Uuid::new_v4());
    drawer.draw(first, &samples_for(0, 40), 10).await;
    drawer.draw(second, &samples_for(1, 40), 10).await;
    assert_eq!(http_removal(&proxy, &as_drawer, second, true).await, 204);
    watcher.wait_for(|v| v.strokes.get(&second).is_some_and(|s| s.removed)).await;

    // Behind the proxy's back, with no event: the first taken back, the second brought back.
    let by = drawer.welcome.participant;
    set_removed_in_database(&db, first, Some(by)).await;
    set_removed_in_database(&db, second, None).await;
    if db.is_postgres() {
        let unreadable = "{\"v\":0,\"events\":[]}";
        let sql = format!("SELECT pg_notify('penmesh_events', '{unreadable}')");
        execute_sql(&db, &sql).await;
    } else {
        proxy.state.fanout.gap_all();
    }
    watcher.wait_for(|v| v.n_synced >= 2).await;
    assert!(watcher.view.strokes[&first].removed, "a stroke taken back during the gap stays shown");
    assert!(!watcher.view.strokes[&second].removed, "a stroke brought back stays hidden");
    assert_eq!(watcher.view.n_lagged, 0, "a gap, not a lag");
}

async fn set_removed_in_database(db: &TestDatabase, stroke: StrokeId, by: Option<Uuid>) {
    let sql = match by {
        Some(by) => {
            format!("UPDATE strokes SET removed_at = 1, removed_by = '{by}' WHERE id = '{stroke}'")
        }
        None => {
            format!("UPDATE strokes SET removed_at = NULL, removed_by = NULL WHERE id = '{stroke}'")
        }
    };
    execute_sql(db, &sql).await;
}
