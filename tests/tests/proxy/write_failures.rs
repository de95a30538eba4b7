//! The write path under injected failures (issue #13): whatever fails, every stroke's stored
//! samples are contiguous from 0 with no overlap, every acknowledged sample is among them, and
//! a stroke that cannot be read does not hide the others.

use std::sync::Arc;
use std::time::Duration;

use futures_util::StreamExt;
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, PointBatch, Points, ServerMessage,
    StrokeBegin, StrokeId, StrokeStatus, decode_server, encode_client,
};
use penmesh_e2e::penmesh_proxy::{CommitFaults, Fault, Frame, stored_pieces};
use penmesh_e2e::{
    TIMEOUT, TestDatabase, TestProxy, TestSession, WsClient, spawn_faulty_proxy_on, stroke_samples,
};
use uuid::Uuid;

const BATCH: usize = 4;

/// A proxy whose writer gets `faults`, committing every 40 ms so that the batches sent at once
/// share transactions.
async fn faulty_proxy(faults: &Arc<CommitFaults>) -> TestProxy {
    spawn_faulty_proxy_on(TestDatabase::fresh().await, Some(faults.clone()), |c| {
        c.commit_interval_ms = 40;
        // Each batch its own request: the faults name a request by the seq its append starts
        // at, and batches sent back to back would otherwise be read together and gathered
        // into one (`--gather-frames`), starting elsewhere.
        c.gather_frames = 1;
    })
    .await
}

/// Sends `samples[from..]` in batches of [`BATCH`] without waiting.
async fn send_from(ws: &mut WsClient, stroke: StrokeId, samples: &[Sample], from: usize) {
    for start in (from..samples.len()).step_by(BATCH) {
        let end = (start + BATCH).min(samples.len());
        ws.points(stroke, start as u64, &samples[start..end]).await;
    }
}

/// What the proxy answered about `stroke` until it has been quiet for half a second: the
/// highest acknowledged seq and the errors naming it.
async fn answers(ws: &mut WsClient, stroke: StrokeId) -> (u64, Vec<ErrorCode>) {
    let (acked, errors, _) = answers_shown(ws, stroke).await;
    (acked, errors)
}

/// Like [`answers`], with the retained samples the drawer was shown.
async fn answers_shown(ws: &mut WsClient, stroke: StrokeId) -> (u64, Vec<ErrorCode>, Vec<Sample>) {
    let (mut acked, mut errors, mut shown) = (0, Vec::new(), Vec::new());
    while let Ok(msg) = tokio::time::timeout(Duration::from_millis(500), ws.recv()).await {
        match msg {
            ServerMessage::Ack(ack) if ack.stroke == stroke => acked = acked.max(ack.upto_seq),
            ServerMessage::Error(err) if err.stroke == Some(stroke) => errors.push(err.code),
            ServerMessage::Retained(r) if r.stroke == stroke => shown.extend(r.points.0),
            _ => {}
        }
    }
    (acked, errors, shown)
}

/// Where a stroke's samples are stored, read straight from the database: its chunk rows and
/// its entries in the append log, each `(seq, n)`.
async fn pieces(db: &TestDatabase, stroke: StrokeId) -> (Vec<(u64, u64)>, Vec<(u64, u64)>) {
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&db.url).await.expect("the test reads the database");
    let pieces = stored_pieces(&pool, stroke).await.unwrap();
    pool.close().await;
    pieces
}

/// The invariant: the stored samples are contiguous from 0 with no overlap, they hold every
/// acknowledged sample, and they are exactly the samples sent. Returns where they end.
/// (The chunk rows are contiguous from 0; the log entries are contiguous among themselves and
/// start at or before the chunks' end: a sample moved into a chunk stays in its log record
/// until the record is deleted, the one copy the layout allows.)
async fn assert_stored_prefix(
    proxy: &TestProxy,
    session: &TestSession,
    stroke: StrokeId,
    sent: &[Sample],
    acked: u64,
) -> u64 {
    let (chunks, log) = pieces(&proxy.db, stroke).await;
    let mut end = 0;
    for (seq, n) in chunks {
        assert_eq!(seq, end, "stroke {stroke}: a chunk at seq {seq} after {end} stored samples");
        assert!(n > 0, "stroke {stroke}: an empty chunk at seq {seq}");
        end += n;
    }
    let mut log_end = log.first().map(|&(seq, _)| seq);
    assert!(
        log_end.is_none_or(|first| first <= end),
        "stroke {stroke}: the log starts at {log_end:?}, past the {end} samples in chunks"
    );
    for (seq, n) in log {
        let at = log_end.expect("set from the first entry");
        assert_eq!(seq, at, "stroke {stroke}: a log entry at seq {seq} after one ending at {at}");
        assert!(n > 0, "stroke {stroke}: an empty log entry at seq {seq}");
        log_end = Some(seq + n);
    }
    let end = end.max(log_end.unwrap_or(0));
    assert!(acked <= end, "stroke {stroke}: acknowledged up to {acked}, stored up to {end}");
    assert_eq!(proxy.raw_samples(session, stroke).await, sent[..end as usize].to_vec());
    end
}

/// Resumes `stroke` on a new connection from where the proxy has it, sends the rest and ends
/// it; checks every sample is stored once.
async fn resume_and_finish(
    proxy: &TestProxy,
    session: &TestSession,
    stroke: StrokeId,
    samples: &[Sample],
    stored: u64,
) {
    let mut ws = proxy.connect(session).await;
    let welcome = ws.hello(vec![stroke]).await;
    let state = &welcome.resume[0];
    assert_eq!(state.next_seq, stored, "Welcome.resume says where the stored samples end");
    assert_ne!(state.status, StrokeStatus::Done);
    ws.begin(stroke).await;
    ws.wait_ack(stroke, stored).await;
    send_from(&mut ws, stroke, samples, stored as usize).await;
    ws.end(stroke, samples.len() as u64).await;
    let (done, _) = ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert!(matches!(done, ServerMessage::StrokeDone(_)));
    assert_stored_prefix(proxy, session, stroke, samples, samples.len() as u64).await;
}

#[tokio::test]
async fn an_append_queued_behind_a_failed_one_is_not_stored_nor_acknowledged() {
    // Arrange: the append at seq 8 fails every time; the ones after it are already queued.
    let faults = CommitFaults::new();
    let proxy = faulty_proxy(&faults).await;
    let session = proxy.create_session().await;
    let (stroke, samples) = (Uuid::new_v4(), stroke_samples(40));
    faults.fail_append(stroke, 8, Fault::Fail, u32::MAX);
    let mut ws = proxy.drawing(&session, stroke).await;

    // Act
    send_from(&mut ws, stroke, &samples, 0).await;
    let (acked, errors, shown) = answers_shown(&mut ws, stroke).await;

    // Assert: nothing past the failure is stored, acknowledged or shown (a batch's retained
    // samples go out with its ack, once it is committed), and the stroke resumes.
    assert!(errors.contains(&ErrorCode::Internal), "{errors:?}");
    assert!(!shown.is_empty(), "the committed batches decided retained samples");
    let committed = &samples[..acked as usize];
    assert!(
        shown.iter().all(|s| committed.contains(s)),
        "the drawer was shown retained samples of batches not committed: {shown:?}"
    );
    let stored = assert_stored_prefix(&proxy, &session, stroke, &samples, acked).await;
    assert_eq!(stored, 8, "stored up to the failed append, not past it");
    assert!(acked <= 8, "acknowledged up to {acked}");
    let info = proxy.stroke_info(&session, stroke).await;
    assert_eq!(info["n_points"], 8);
    drop(ws);
    faults.clear();
    resume_and_finish(&proxy, &session, stroke, &samples, stored).await;
}

/// Batches read together are stored as one request (`--gather-frames`, the default 16); when
/// it fails, none of them is acknowledged, stored or shown, the drawer is told, and the stroke
/// resumes and is stored whole.
#[tokio::test]
async fn gathered_batches_that_fail_together_are_neither_stored_nor_acknowledged() {
    // Arrange: every frame (hello, begin, ten batches) waits in the connection's queue before
    // its task first runs (the test's runtime has one thread), so the batches are read in one
    // burst and gathered; the request holding sample 8 fails every time.
    let faults = CommitFaults::new();
    let proxy =
        spawn_faulty_proxy_on(TestDatabase::fresh().await, Some(faults.clone()), |_| {}).await;
    let session = proxy.create_session().await;
    let (stroke, samples) = (Uuid::new_v4(), stroke_samples(40));
    faults.fail_append(stroke, 8, Fault::Fail, u32::MAX);
    let guard = proxy.state.join_session(session.session).expect("room in the session");
    let (to_server, from_client) = tokio::sync::mpsc::channel::<Frame>(16);
    let frame = |msg: ClientMessage| Frame::Binary(encode_client(&msg));
    let hello = Hello {
        protocol: PROTOCOL_VERSION,
        client: "gathered".into(),
        name: None,
        resume: vec![],
        // The session's drawer, as the connection that resumes the stroke below.
        key: Some(session.key.clone()),
    };
    to_server.send(frame(ClientMessage::Hello(hello))).await.unwrap();
    let begin = StrokeBegin {
        stroke,
        brush: Default::default(),
        device: None,
        params: None,
        placement: None,
        solid: None,
    };
    to_server.send(frame(ClientMessage::StrokeBegin(begin))).await.unwrap();
    for (k, chunk) in samples.chunks(BATCH).enumerate() {
        let points = Points { stroke, seq: (k * BATCH) as u64, points: PointBatch(chunk.to_vec()) };
        to_server.send(frame(ClientMessage::Points(points))).await.unwrap();
    }
    let (to_client, mut from_server) = tokio::sync::mpsc::channel::<Frame>(64);
    let stream = futures_util::stream::unfold(from_client, |mut rx| async move {
        rx.recv().await.map(|f| (Ok::<_, std::convert::Infallible>(f), rx))
    })
    .boxed();
    let task = tokio::spawn(penmesh_e2e::penmesh_proxy::serve(
        proxy.state.clone(),
        session.session,
        guard,
        tokio_util::sync::PollSender::new(to_client),
        stream,
    ));

    // Act: read the answers up to the failure's error.
    let (mut acks, mut shown) = (Vec::new(), 0);
    loop {
        let Some(Frame::Binary(bytes)) =
            tokio::time::timeout(TIMEOUT, from_server.recv()).await.expect("an answer in time")
        else {
            panic!("the connection ended before the failure was told");
        };
        match decode_server(&bytes, usize::MAX).unwrap() {
            ServerMessage::Ack(ack) => acks.push(ack.upto_seq),
            ServerMessage::Retained(r) => shown += r.points.0.len(),
            ServerMessage::Error(e) if e.stroke == Some(stroke) => {
                assert_eq!(e.code, ErrorCode::Internal, "{e:?}");
                break;
            }
            _ => {}
        }
    }
    drop(to_server);
    task.await.unwrap();

    // Assert: only the begin was acknowledged (one batch's ack would say the batches were
    // stored one by one), nothing stored or shown; then the stroke resumes from 0.
    assert_eq!(acks, [0], "acknowledged");
    assert_eq!(shown, 0, "retained samples of batches not committed were shown");
    let stored = assert_stored_prefix(&proxy, &session, stroke, &samples, 0).await;
    assert_eq!(stored, 0);
    faults.clear();
    resume_and_finish(&proxy, &session, stroke, &samples, 0).await;
}

#[tokio::test]
async fn a_commit_that_succeeded_but_reported_failure_is_not_stored_twice() {
    // Arrange: the transaction holding the append at seq 4 commits, then reports failure; the
    // group merged the stroke's batches into one row, and the retry goes request by request.
    let faults = CommitFaults::new();
    let proxy = faulty_proxy(&faults).await;
    let session = proxy.create_session().await;
    let (stroke, samples) = (Uuid::new_v4(), stroke_samples(40));
    faults.fail_append(stroke, 4, Fault::FailAfterCommit, 1);
    let mut ws = proxy.drawing(&session, stroke).await;

    // Act
    send_from(&mut ws, stroke, &samples, 0).await;
    let (acked, errors) = answers(&mut ws, stroke).await;

    // Assert: every batch is acknowledged once stored, and stored once.
    assert!(errors.is_empty(), "{errors:?}");
    assert_eq!(acked, 40);
    assert_stored_prefix(&proxy, &session, stroke, &samples, acked).await;
    ws.end(stroke, 40).await;
    let (done, _) = ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert!(matches!(done, ServerMessage::StrokeDone(_)));
}

#[tokio::test]
async fn many_failed_commits_and_dropped_connections_leave_every_stroke_contiguous() {
    // Arrange: three pens begin a stroke each; then the next ten transactions fail, before
    // or after COMMIT, and two pens drop their connection with appends still queued.
    let faults = CommitFaults::new();
    let proxy = faulty_proxy(&faults).await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(120);
    let strokes: Vec<StrokeId> = (0..3).map(|_| Uuid::new_v4()).collect();
    let mut clients = Vec::new();
    for &stroke in &strokes {
        let ws = proxy.drawing(&session, stroke).await;
        clients.push(ws);
    }
    for k in 1..=10 {
        let fault = if k % 3 == 0 { Fault::FailAfterCommit } else { Fault::Fail };
        faults.fail_transaction(k, fault);
    }

    // Act: every pen sends its whole stroke at once; the last two hang up straight after.
    for (ws, &stroke) in clients.iter_mut().zip(&strokes) {
        send_from(ws, stroke, &samples, 0).await;
    }
    let mut first = clients.remove(0);
    drop(clients);
    let (acked, _) = answers(&mut first, strokes[0]).await;
    drop(first);
    tokio::time::sleep(Duration::from_millis(300)).await;

    // Assert: each stroke is a stored prefix holding what was acknowledged, and resumes.
    for (i, &stroke) in strokes.iter().enumerate() {
        let acked = if i == 0 { acked } else { 0 };
        let stored = assert_stored_prefix(&proxy, &session, stroke, &samples, acked).await;
        resume_and_finish(&proxy, &session, stroke, &samples, stored).await;
    }
}

#[tokio::test]
async fn an_unreadable_stroke_is_reported_and_does_not_hide_the_others() {
    // Arrange: two strokes in progress, then one's stored samples are damaged.
    let proxy = spawn_faulty_proxy_on(TestDatabase::fresh().await, None, |_| {}).await;
    let session = proxy.create_session().await;
    let samples = stroke_samples(20);
    let (good, bad) = (Uuid::new_v4(), Uuid::new_v4());
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    for stroke in [good, bad] {
        ws.begin(stroke).await;
        ws.points(stroke, 0, &samples).await;
        ws.wait_ack(stroke, 20).await;
    }
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&proxy.db.url).await.unwrap();
    // A chunk row that does not decode (the samples are in the log while the stroke is drawn).
    sqlx::query(
        "INSERT INTO stroke_chunks (stroke_id, seq, n, layout, data) VALUES ($1, 0, 20, 1, $2)",
    )
    .bind(bad.to_string())
    .bind(vec![1u8, 2, 3])
    .execute(&pool)
    .await
    .unwrap();
    pool.close().await;

    // Act: someone joins the session.
    let mut peer = proxy.connect(&session).await;
    peer.hello(vec![]).await;
    let mut before = Vec::new();
    let synced = loop {
        match peer.recv_any().await {
            ServerMessage::Synced(synced) => break synced,
            // A history's whole strokes come several to a message.
            ServerMessage::PeerStrokes(strokes) => before.extend(strokes.messages()),
            other => before.push(other),
        }
    };

    // Assert: the damaged stroke is named in an error, the other one arrives whole.
    assert_eq!(synced.n_strokes, 1);
    let reported: Vec<_> = before
        .iter()
        .filter_map(|m| match m {
            ServerMessage::Error(e) => Some((e.code, e.stroke)),
            _ => None,
        })
        .collect();
    assert_eq!(reported, vec![(ErrorCode::Internal, Some(bad))]);
    assert!(
        before.iter().any(|m| matches!(m, ServerMessage::PeerRetained(r) if r.stroke == good)),
        "{before:?}"
    );
}

#[tokio::test]
async fn a_batch_whose_begin_failed_is_neither_stored_nor_acknowledged() {
    // Arrange: every transaction holding the stroke's begin fails. A client streams: its
    // batches follow the begin before the begin's answer comes back.
    let faults = CommitFaults::new();
    let proxy = faulty_proxy(&faults).await;
    let session = proxy.create_session().await;
    let (stroke, samples) = (Uuid::new_v4(), stroke_samples(12));
    faults.fail_begin(stroke, Fault::Fail, u32::MAX);
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;

    // Act
    ws.begin(stroke).await;
    send_from(&mut ws, stroke, &samples, 0).await;
    let mut acks = Vec::new();
    let mut errors = Vec::new();
    while let Ok(msg) = tokio::time::timeout(Duration::from_millis(500), ws.recv()).await {
        match msg {
            ServerMessage::Ack(ack) if ack.stroke == stroke => acks.push(ack.upto_seq),
            ServerMessage::Error(err) if err.stroke == Some(stroke) => errors.push(err),
            _ => {}
        }
    }

    // Assert: a stroke exists before anything of it is acknowledged; nothing of it is stored,
    // and no answer carries the database's own words.
    assert!(acks.is_empty(), "acknowledged {acks:?} of a stroke that was never created");
    assert!(errors.iter().any(|e| e.code == ErrorCode::Internal), "{errors:?}");
    assert!(
        errors.iter().all(|e| !e.message.contains("injected")),
        "an answer carries the failure's own text: {errors:?}"
    );
    assert_eq!(pieces(&proxy.db, stroke).await, (vec![], vec![]));
    let raw = proxy.get(&format!("/v1/strokes/{stroke}/raw"), &session).send().await.unwrap();
    assert_eq!(raw.status(), 404);
    // Once the begin commits, the stroke is drawn from 0.
    faults.clear();
    ws.begin(stroke).await;
    ws.wait_ack(stroke, 0).await;
    send_from(&mut ws, stroke, &samples, 0).await;
    ws.wait_ack(stroke, 12).await;
    assert_stored_prefix(&proxy, &session, stroke, &samples, 12).await;
}

#[tokio::test]
async fn samples_the_log_cannot_move_are_set_aside_and_other_pens_go_on() {
    // Arrange: a stroke with acknowledged samples in the append log loses its row behind the
    // writer's back (what a begin that failed left before the writer checked), while a pen of
    // another session draws on.
    let proxy = spawn_faulty_proxy_on(TestDatabase::fresh().await, None, |_| {}).await;
    let session = proxy.create_session().await;
    let orphan = Uuid::new_v4();
    let mut idle = proxy.drawing(&session, orphan).await;
    idle.points(orphan, 0, &stroke_samples(8)).await;
    idle.wait_ack(orphan, 8).await;
    sqlx::any::install_default_drivers();
    let pool = sqlx::AnyPool::connect(&proxy.db.url).await.unwrap();
    sqlx::query("DELETE FROM strokes WHERE id = $1")
        .bind(orphan.to_string())
        .execute(&pool)
        .await
        .unwrap();
    let other = proxy.create_session().await;
    let mut pen = proxy.connect(&other).await;
    pen.hello(vec![]).await;

    // Act: eight strokes of a second each, a batch every 50 ms, past several of the writer's
    // moves of the log.
    let samples = stroke_samples(80);
    let mut errors = Vec::new();
    for _ in 0..8 {
        let stroke = Uuid::new_v4();
        pen.begin(stroke).await;
        for (i, batch) in samples.chunks(BATCH).enumerate() {
            pen.points(stroke, (i * BATCH) as u64, batch).await;
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        pen.end(stroke, samples.len() as u64).await;
        loop {
            match pen.recv().await {
                ServerMessage::StrokeDone(done) if done.stroke == stroke => break,
                ServerMessage::Error(err) if err.stroke == Some(stroke) => {
                    errors.push(err);
                    break;
                }
                ServerMessage::Error(err) => errors.push(err),
                _ => {}
            }
        }
    }

    // Assert: the other pen saw no error; the orphan's samples are set aside, counted, and no
    // longer hold the log's records (the log is trimmed as usual).
    assert!(errors.is_empty(), "{errors:?}");
    let set_aside: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM stroke_log_set_aside WHERE stroke_id = $1")
            .bind(orphan.to_string())
            .fetch_one(&pool)
            .await
            .unwrap();
    assert!(set_aside >= 1, "the orphan's log entries are kept aside");
    let records: i64 =
        sqlx::query_scalar("SELECT COUNT(*) FROM stroke_log").fetch_one(&pool).await.unwrap();
    assert!(records < 100, "the log holds {records} records: it is not trimmed");
    assert!(proxy.metrics().await.contains("penmesh_log_set_aside_total"));
    pool.close().await;
    drop(idle);
}
