//! Taking strokes back (undo, the eraser) and bringing them back (redo), as people do it in a
//! shared session: the drawer on one replica, a watcher and a late joiner on the other (two
//! replicas with PostgreSQL, one proxy on SQLite). Every connection hears of it, the history,
//! the strokes list and the mesh bundle leave a removed stroke out, nothing of it is lost in
//! storage, and nobody but its drawer may take it back.

use penmesh::protocol::{
    ClientMessage, ErrorCode, ServerMessage, StrokeId, StrokeRef, decode_mesh_bundle,
};
use penmesh_e2e::penmesh_proxy::{CommitFaults, Fault};
use penmesh_e2e::{
    TestDatabase, TestProxy, TestSession, count_rows, minimal_glb, spawn_faulty_proxy_on,
};
use uuid::Uuid;

use crate::helpers::{Participant, one_or_two_replicas, put_mesh, samples_for};

/// The participant's request to take back (`remove`) or bring back `stroke`.
fn removal(stroke: StrokeId, remove: bool) -> ClientMessage {
    if remove {
        ClientMessage::RemoveStroke(StrokeRef { stroke })
    } else {
        ClientMessage::RestoreStroke(StrokeRef { stroke })
    }
}

/// Reads until the answer about `stroke`: `Ok(removed)` for `StrokeRemoved`/`StrokeRestored`,
/// `Err(code)` for an error about it.
async fn answer(p: &mut Participant, stroke: StrokeId) -> Result<bool, ErrorCode> {
    loop {
        match p.recv().await {
            ServerMessage::StrokeRemoved(r) if r.stroke == stroke => return Ok(true),
            ServerMessage::StrokeRestored(r) if r.stroke == stroke => return Ok(false),
            ServerMessage::Error(e) if e.stroke == Some(stroke) => return Err(e.code),
            ServerMessage::Error(e) => panic!("unexpected error: {e:?}"),
            _ => {}
        }
    }
}

/// `DELETE /v1/strokes/{stroke}` (`remove`) or `POST …/restore` as `who`; the status.
pub(crate) async fn http_removal(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: StrokeId,
    remove: bool,
) -> u16 {
    let request = if remove {
        proxy.http.delete(proxy.url(&format!("/v1/strokes/{stroke}")))
    } else {
        proxy.http.post(proxy.url(&format!("/v1/strokes/{stroke}/restore")))
    };
    let response = request
        .bearer_auth(&who.token)
        .header(penmesh::protocol::KEY_HEADER, &who.key)
        .send()
        .await
        .unwrap();
    response.status().as_u16()
}

/// The ids of the session's strokes list (`?include=removed` when `removed`), in order, and
/// who took each back.
async fn listed(
    proxy: &TestProxy,
    session: &TestSession,
    removed: bool,
) -> Vec<(StrokeId, Option<String>)> {
    let query = if removed { "?include=removed" } else { "" };
    let list =
        proxy.get_json(&format!("/v1/sessions/{}/strokes{query}", session.session), session).await;
    list["strokes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let by = s["removed"]["by"].as_str().map(str::to_string);
            (s["id"].as_str().unwrap().parse().unwrap(), by)
        })
        .collect()
}

/// The strokes of the session's mesh bundle, in order, and its ETag.
pub(crate) async fn bundled(proxy: &TestProxy, session: &TestSession) -> (Vec<StrokeId>, String) {
    let response =
        proxy.get(&format!("/v1/sessions/{}/meshes", session.session), session).send().await;
    let response = response.unwrap();
    assert_eq!(response.status(), 200);
    let etag = response.headers()["etag"].to_str().unwrap().to_string();
    let meshes = decode_mesh_bundle(&response.bytes().await.unwrap()).unwrap();
    (meshes.iter().map(|m| m.stroke).collect(), etag)
}

/// Every stored part of a stroke, read through the API: its raw samples, its simplified
/// samples with their indices, and its mesh.
async fn stored_parts(proxy: &TestProxy, session: &TestSession, stroke: StrokeId) -> Vec<String> {
    let mut parts = Vec::new();
    for path in ["raw", "simplified"] {
        let body = proxy.get_json(&format!("/v1/strokes/{stroke}/{path}"), session).await;
        parts.push(format!("{} {}", body["indices"], body["samples"]));
    }
    let response = proxy.get(&format!("/v1/strokes/{stroke}/mesh"), session).send().await;
    let response = response.unwrap();
    assert_eq!(response.status(), 200, "GET /v1/strokes/{stroke}/mesh");
    parts.push(hex_digest(&response.bytes().await.unwrap()));
    parts
}

fn hex_digest(bytes: &[u8]) -> String {
    use sha2::Digest;
    format!("{} bytes, sha256 {:x}", bytes.len(), sha2::Sha256::digest(bytes))
}

#[tokio::test]
async fn a_stroke_taken_back_and_brought_back_reaches_everyone_and_nothing_of_it_is_lost() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let (a, b) = (&proxies[0], proxies.last().unwrap());
    let session = a.create_session().await;
    let mut drawer = Participant::join(a, &session, "drawer").await;
    let mut watcher = Participant::join(b, &session, "watcher").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let as_watcher = TestSession { key: watcher.key.clone(), ..session.clone() };
    let strokes: Vec<StrokeId> = (0..3).map(|_| Uuid::new_v4()).collect();
    for (k, stroke) in strokes.iter().enumerate() {
        drawer.draw(*stroke, &samples_for(k, 120), 16).await;
        put_mesh(b, &drawer, &session, *stroke).await;
    }
    watcher.wait_for(|v| v.n_meshes() == 3).await;
    let last = strokes[2];
    let before = stored_parts(b, &session, last).await;
    let (_, etag_before) = bundled(a, &session).await;
    let rows_before = stored_rows(a, last).await;

    // The drawer takes its last stroke back: answered, and the watcher on the other replica
    // hears of it.
    drawer.ws.send(&removal(last, true)).await;
    assert_eq!(answer(&mut drawer, last).await, Ok(true));
    watcher.wait_for(|v| v.strokes[&last].removed).await;

    // Idempotent: taken back again, the same answer.
    drawer.ws.send(&removal(last, true)).await;
    assert_eq!(answer(&mut drawer, last).await, Ok(true));

    // The watcher may not take back the drawer's strokes, over the socket or HTTP; nothing
    // changes.
    watcher.ws.send(&removal(strokes[0], true)).await;
    assert_eq!(answer(&mut watcher, strokes[0]).await, Err(ErrorCode::NotOwner));
    assert_eq!(http_removal(b, &as_watcher, strokes[0], true).await, 403);
    assert_eq!(http_removal(b, &as_watcher, last, false).await, 403);
    let unknown = Uuid::new_v4();
    watcher.ws.send(&removal(unknown, true)).await;
    assert_eq!(answer(&mut watcher, unknown).await, Err(ErrorCode::UnknownStroke));
    // Another session's token does not find the stroke at all.
    let other = a.create_session().await;
    assert_eq!(http_removal(a, &other, strokes[0], true).await, 404);

    // What is listed and bundled leaves it out; everything of it is still stored and readable.
    let without: Vec<(StrokeId, Option<String>)> =
        strokes[..2].iter().map(|s| (*s, None)).collect();
    assert_eq!(listed(b, &session, false).await, without);
    let mut with = without.clone();
    with.push((last, Some(drawer.welcome.participant.to_string())));
    assert_eq!(listed(b, &session, true).await, with);
    let (in_bundle, etag_removed) = bundled(b, &session).await;
    assert_eq!(in_bundle, strokes[..2].to_vec());
    assert_ne!(etag_removed, etag_before, "the bundle's ETag changes with a removal");
    assert!(stored_parts(a, &session, last).await == before, "the stroke's parts changed");
    assert_eq!(stored_rows(a, last).await, rows_before, "nothing of the stroke is deleted");

    // A late joiner's history leaves it out.
    let mut late = Participant::join(b, &session, "late").await;
    assert_eq!(late.view.strokes.keys().copied().collect::<Vec<_>>(), sorted(&strokes[..2]));

    // Brought back over HTTP: the watcher sees it again, the late joiner gets all of it.
    assert_eq!(http_removal(b, &as_drawer, last, false).await, 204);
    watcher.wait_for(|v| !v.strokes[&last].removed).await;
    late.wait_for(|v| v.strokes.get(&last).is_some_and(|s| s.done && s.meshes == 1)).await;
    assert_eq!(late.view.strokes[&last], watcher.view.strokes[&last]);
    assert_eq!(answer(&mut drawer, last).await, Ok(false), "the drawer hears of it too");
    assert_eq!(listed(a, &session, false).await.len(), 3);
    assert_eq!(bundled(a, &session).await, (strokes.clone(), etag_before));

    // Taken back over HTTP and brought back over the socket (redo).
    assert_eq!(http_removal(a, &as_drawer, strokes[0], true).await, 204);
    assert_eq!(http_removal(a, &as_drawer, strokes[0], true).await, 204, "idempotent");
    assert_eq!(answer(&mut drawer, strokes[0]).await, Ok(true));
    late.wait_for(|v| v.strokes[&strokes[0]].removed).await;
    drawer.ws.send(&removal(strokes[0], false)).await;
    assert_eq!(answer(&mut drawer, strokes[0]).await, Ok(false));
    late.wait_for(|v| !v.strokes[&strokes[0]].removed).await;
    watcher.wait_for(|v| !v.strokes[&strokes[0]].removed).await;

    // The drawer again, after a reload: its strokes come with the history; taken back over
    // the socket and brought back over HTTP, it hears both.
    let mut reloaded = Participant::join_resuming(b, &session, "drawer", &drawer.key, vec![]).await;
    assert_eq!(reloaded.view.strokes.len(), 3);
    reloaded.ws.send(&removal(strokes[1], true)).await;
    assert_eq!(answer(&mut reloaded, strokes[1]).await, Ok(true));
    assert_eq!(http_removal(a, &as_drawer, strokes[1], false).await, 204);
    assert_eq!(answer(&mut reloaded, strokes[1]).await, Ok(false));
    watcher.wait_for(|v| !v.strokes[&strokes[1]].removed).await;
}

fn sorted(strokes: &[StrokeId]) -> Vec<StrokeId> {
    let mut sorted = strokes.to_vec();
    sorted.sort();
    sorted
}

/// The rows a stroke has in each table, straight from the database.
async fn stored_rows(proxy: &TestProxy, stroke: StrokeId) -> Vec<i64> {
    let mut rows = Vec::new();
    for table in ["strokes", "simplified", "meshes"] {
        let column = if table == "strokes" { "id" } else { "stroke_id" };
        let sql = format!("SELECT COUNT(*) FROM {table} WHERE {column} = '{stroke}'");
        rows.push(count_rows(&proxy.db, &sql).await);
    }
    let sql = format!(
        "SELECT CAST(COALESCE(SUM(n), 0) AS BIGINT) FROM stroke_chunks WHERE stroke_id = '{stroke}'"
    );
    rows.push(count_rows(&proxy.db, &sql).await);
    rows
}

#[tokio::test]
async fn a_stroke_still_being_drawn_cannot_be_taken_back() {
    let proxies = one_or_two_replicas(|_| {}).await;
    let proxy = &proxies[0];
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(proxy, &session, "drawer").await;
    let as_drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let stroke = Uuid::new_v4();
    let samples = samples_for(0, 50);
    drawer.begin(stroke).await;
    drawer.send_points(stroke, &samples, 0, 20, 10).await;
    drawer.wait_ack(stroke, 20).await;
    drawer.ws.send(&removal(stroke, true)).await;
    assert_eq!(answer(&mut drawer, stroke).await, Err(ErrorCode::StrokeOpen));
    assert_eq!(http_removal(proxy, &as_drawer, stroke, true).await, 409);
    // The stroke goes on as if nothing was asked.
    drawer.send_points(stroke, &samples, 20, 50, 10).await;
    drawer.wait_ack(stroke, 50).await;
    drawer.finish(stroke, 50).await;
    assert_eq!(http_removal(proxy, &as_drawer, stroke, true).await, 204);
    assert!(listed(proxy, &session, false).await.is_empty());
    // A mesh can still be stored for a stroke taken back (a build in flight); it stays out of
    // the bundle until the stroke is brought back.
    let response = proxy.put_mesh(&as_drawer, stroke, minimal_glb(3, 3)).send().await.unwrap();
    assert_eq!(response.status(), 200);
    assert!(bundled(proxy, &session).await.0.is_empty());
    assert_eq!(http_removal(proxy, &as_drawer, stroke, false).await, 204);
    assert_eq!(bundled(proxy, &session).await.0, vec![stroke]);
}

/// A removal whose commit fails changes nothing: its drawer is told to try again, nobody else
/// hears of it and the stroke stays listed; trying again takes it back, and everyone hears of
/// it once. A commit that took effect but was reported failed (the reply lost) is answered on
/// the next try, which changes nothing more; the others hear of it once, with the commit
/// (PostgreSQL: its notification) or with the next try (SQLite).
#[tokio::test]
async fn a_removal_whose_commit_fails_changes_nothing_until_it_is_tried_again() {
    let faults = CommitFaults::new();
    let proxy =
        spawn_faulty_proxy_on(TestDatabase::fresh().await, Some(faults.clone()), |_| {}).await;
    let session = proxy.create_session().await;
    let mut drawer = Participant::join(&proxy, &session, "drawer").await;
    let mut watcher = Participant::join(&proxy, &session, "watcher").await;
    let strokes = [Uuid::new_v4(), Uuid::new_v4()];
    for (k, stroke) in strokes.into_iter().enumerate() {
        drawer.draw(stroke, &samples_for(k, 30), 10).await;
    }
    watcher.wait_for(|v| v.n_done() == 2).await;
    let removed = |listed: Vec<(StrokeId, Option<String>)>| {
        listed.into_iter().filter(|(_, by)| by.is_some()).map(|(id, _)| id).collect::<Vec<_>>()
    };

    for (stroke, fault) in strokes.into_iter().zip([Fault::Fail, Fault::FailAfterCommit]) {
        faults.fail_removal(stroke, fault, 1);
        drawer.ws.send(&removal(stroke, true)).await;
        assert_eq!(answer(&mut drawer, stroke).await, Err(ErrorCode::Internal), "{fault:?}");
        let stored = removed(listed(&proxy, &session, true).await);
        match fault {
            Fault::Fail => assert!(!stored.contains(&stroke), "a failed removal was stored"),
            Fault::FailAfterCommit => assert!(stored.contains(&stroke), "the commit took effect"),
        }
        if fault == Fault::Fail {
            // Nobody else has heard of it.
            let quiet = tokio::time::timeout(std::time::Duration::from_millis(300), watcher.recv());
            assert!(quiet.await.is_err(), "the watcher heard of a removal that was not stored");
        }

        drawer.ws.send(&removal(stroke, true)).await;
        assert_eq!(answer(&mut drawer, stroke).await, Ok(true), "{fault:?}: tried again");
        // The view refuses a second `StrokeRemoved`: the watcher hears of it exactly once.
        watcher.wait_for(|v| v.strokes[&stroke].removed).await;
        assert!(removed(listed(&proxy, &session, true).await).contains(&stroke));
    }
    assert!(listed(&proxy, &session, false).await.is_empty());
}
