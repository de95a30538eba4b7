//! What deploying on an orchestrator relies on (docs/deploy.md): `/readyz` answers within its
//! deadline when the database does not, a pen whose instance is scaled away resumes on another,
//! and the migrations, the listener and the lock connection go to `direct_database_url`
//! (PostgreSQL).

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use penmesh::protocol::{ErrorCode, ServerMessage, StrokeStatus};
use penmesh_e2e::{
    Incoming, TestDatabase, spawn_proxy_on, spawn_proxy_with, spawn_replica, stroke_samples,
};
use penmesh_proxy::READY_DB_DEADLINE;
use uuid::Uuid;

#[tokio::test]
async fn readyz_answers_503_within_its_deadline_while_the_database_hangs() {
    // Arrange: one pool connection, held by the test: the database "hangs" for the proxy.
    let proxy = spawn_proxy_with(|c| c.db_max_connections = 1).await;
    let client = reqwest::Client::new();
    let url = proxy.url("/readyz");
    assert_eq!(client.get(&url).send().await.unwrap().status(), 200);
    let held = proxy.state.store.pool().acquire().await.unwrap();

    // Act: ten probes at once.
    let started = Instant::now();
    let probes = (0..10).map(|_| {
        let (client, url) = (client.clone(), url.clone());
        tokio::spawn(async move {
            let response = client.get(&url).send().await.unwrap();
            (response.status(), started.elapsed())
        })
    });
    let answers = futures_util::future::join_all(probes).await;

    // Assert: every probe is answered 503 at the deadline, none waits for the pool's timeout.
    for answer in answers {
        let (status, elapsed) = answer.unwrap();
        assert_eq!(status, 503);
        assert!(elapsed >= READY_DB_DEADLINE, "answered before the deadline: {elapsed:?}");
        assert!(elapsed < READY_DB_DEADLINE + Duration::from_secs(2), "piled up: {elapsed:?}");
    }
    drop(held);
    assert_eq!(client.get(&url).send().await.unwrap().status(), 200);
}

#[tokio::test]
async fn a_pen_whose_instance_is_scaled_away_resumes_on_another() {
    // Arrange: instance A (with PostgreSQL, B runs beside it, as a Knative revision scales).
    let db = TestDatabase::fresh().await;
    let postgres = db.is_postgres();
    let a = spawn_replica(db.clone(), |_| {}).await;
    let b = if postgres { Some(spawn_replica(db.clone(), |_| {}).await) } else { None };
    let session = a.create_session().await;
    let samples = stroke_samples(300);
    let stroke = Uuid::new_v4();
    let mut ws = a.connect(&session).await;
    ws.hello(vec![]).await;
    ws.begin(stroke).await;
    ws.points(stroke, 0, &samples[..120]).await;
    ws.wait_ack(stroke, 120).await;

    // Act: the platform scales A away (SIGTERM); the pen reconnects through the same address,
    // which now reaches B (or, scaled to zero and back on SQLite, a new instance).
    a.trigger_shutdown();
    ws.expect_error(ErrorCode::ShuttingDown).await;
    let close = loop {
        if let Incoming::Closed(close) = ws.next().await {
            break close;
        }
    };
    assert_eq!(close.map(|c| c.0), Some(1001));
    let db = a.stop().await;
    let b = match b {
        Some(b) => b,
        None => spawn_proxy_on(db, |_| {}).await,
    };
    let mut ws = b.connect(&session).await;
    let welcome = ws.hello(vec![stroke]).await;

    // Assert: it resumes from the last acknowledged sample and ends with every sample stored.
    assert_eq!(welcome.resume[0].next_seq, 120);
    let status = welcome.resume[0].status;
    assert!(matches!(status, StrokeStatus::Open | StrokeStatus::Interrupted), "{status:?}");
    ws.points(stroke, 120, &samples[120..]).await;
    ws.end(stroke, 300).await;
    ws.recv_until(|m| matches!(m, ServerMessage::StrokeDone(_))).await;
    assert_eq!(b.raw_samples(&session, stroke).await, samples);
}

#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn the_migrations_the_listener_and_the_locks_use_the_direct_database_url() {
    // Arrange: a relay to the same server that counts the connections made through it.
    let db = TestDatabase::fresh().await;
    let target: sqlx::postgres::PgConnectOptions = db.url.parse().unwrap();
    let server = format!("{}:{}", target.get_host(), target.get_port());
    let relay = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let relay_port = relay.local_addr().unwrap().port();
    let through_relay = Arc::new(AtomicUsize::new(0));
    let counter = through_relay.clone();
    tokio::spawn(async move {
        while let Ok((mut inbound, _)) = relay.accept().await {
            counter.fetch_add(1, Ordering::SeqCst);
            let server = server.clone();
            tokio::spawn(async move {
                let mut outbound = tokio::net::TcpStream::connect(server).await.unwrap();
                let _ = tokio::io::copy_bidirectional(&mut inbound, &mut outbound).await;
            });
        }
    });
    let host = format!("{}:{}", target.get_host(), target.get_port());
    let direct = db.url.replacen(&host, &format!("127.0.0.1:{relay_port}"), 1);
    assert_ne!(direct, db.url, "the test URL names {host}");

    // Act
    let proxy = spawn_proxy_on(db, |c| c.direct_database_url = Some(direct.into())).await;
    let session = proxy.create_session().await;
    let stroke = Uuid::new_v4();
    let _ws = proxy.drawing(&session, stroke).await;

    // Assert: exactly the migrations, the listener and the lock connection went through it;
    // the pool and the writer did not.
    assert_eq!(through_relay.load(Ordering::SeqCst), 3);
}
