//! End-to-end test helpers: [`spawn_proxy`] starts the real proxy on port 0 with a fresh
//! database (a SQLite file in a temporary folder, or a fresh PostgreSQL database when
//! `PENMESH_TEST_POSTGRES_URL` is set: then a PostgreSQL failure fails the test, it never
//! skips), and [`TestProxy`] / [`WsClient`] speak HTTP and the WebSocket protocol to it.

use std::sync::Arc;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, ErrorMessage, Hello, KEY_HEADER, PROTOCOL_VERSION, PointBatch,
    Points, ServerMessage, StrokeBegin, StrokeEnd, StrokeId, Welcome, decode_server,
    decode_server_json, encode_client, encode_client_json,
};
use penmesh_proxy::{AppState, Application, Config};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

pub use penmesh_proxy;

/// How long any single wait in a test may take.
pub const TIMEOUT: Duration = Duration::from_secs(15);

/// The environment variable that points the suite at PostgreSQL.
pub const POSTGRES_ENV: &str = "PENMESH_TEST_POSTGRES_URL";

/// A fresh, empty database for one test. A SQLite database lives as long as this value.
#[derive(Debug, Clone)]
pub struct TestDatabase {
    pub url: String,
    _dir: Option<Arc<tempfile::TempDir>>,
}

impl TestDatabase {
    /// A new SQLite file, or a new PostgreSQL database when [`POSTGRES_ENV`] is set.
    pub async fn fresh() -> TestDatabase {
        match std::env::var(POSTGRES_ENV) {
            Ok(url) if !url.is_empty() => TestDatabase::fresh_postgres(&url).await,
            _ => {
                let dir = tempfile::tempdir().expect("temporary folder");
                let url = format!("sqlite://{}", dir.path().join("penmesh.db").display());
                TestDatabase { url, _dir: Some(Arc::new(dir)) }
            }
        }
    }

    async fn fresh_postgres(admin_url: &str) -> TestDatabase {
        use sqlx::Connection;
        let name = format!("penmesh_{}", uuid::Uuid::new_v4().simple());
        let mut conn = sqlx::PgConnection::connect(admin_url)
            .await
            .unwrap_or_else(|e| panic!("{POSTGRES_ENV} is set but PostgreSQL is unreachable: {e}"));
        sqlx::query(&format!("CREATE DATABASE {name}"))
            .execute(&mut conn)
            .await
            .unwrap_or_else(|e| panic!("creating database {name}: {e}"));
        let _ = conn.close().await;
        let (base, query) = match admin_url.split_once('?') {
            Some((base, query)) => (base, format!("?{query}")),
            None => (admin_url, String::new()),
        };
        let scheme_end = base.find("://").map(|i| i + 3).unwrap_or(0);
        let host_part = match base[scheme_end..].find('/') {
            Some(slash) => &base[..scheme_end + slash],
            None => base,
        };
        TestDatabase { url: format!("{host_part}/{name}{query}"), _dir: None }
    }

    /// A database that exists already at `url` (the caller made it and keeps it alive).
    pub fn existing(url: String) -> TestDatabase {
        TestDatabase { url, _dir: None }
    }

    pub fn is_postgres(&self) -> bool {
        self.url.starts_with("postgres")
    }
}

/// Settings for tests: port 0 on localhost, the given database, short grace periods.
pub fn test_config(db: &TestDatabase) -> Config {
    let mut config = Config::defaults();
    config.host = "127.0.0.1".into();
    config.port = 0;
    config.database_url = db.url.clone().into();
    config.shutdown_grace_secs = 5;
    config.claim_wait_ms = 3000;
    config
}

/// A running proxy.
#[derive(Debug)]
pub struct TestProxy {
    pub address: String,
    pub port: u16,
    pub db: TestDatabase,
    pub http: reqwest::Client,
    /// The running application's shared state (fan-out, claims, settings).
    pub state: AppState,
    shutdown: tokio_util::sync::CancellationToken,
    task: tokio::task::JoinHandle<anyhow::Result<()>>,
    /// The runtime of a replica started by [`spawn_replica`]: dropping it kills the replica.
    runtime: Option<ReplicaRuntime>,
}

impl TestProxy {
    /// The handle of an application that is running: its port, shutdown and state.
    fn started(
        db: TestDatabase,
        (port, shutdown, state): (u16, tokio_util::sync::CancellationToken, AppState),
        task: tokio::task::JoinHandle<anyhow::Result<()>>,
        runtime: Option<ReplicaRuntime>,
    ) -> TestProxy {
        let address = format!("http://127.0.0.1:{port}");
        let http = reqwest::Client::new();
        TestProxy { address, port, db, http, state, shutdown, task, runtime }
    }
}

/// A runtime of its own for one replica. Dropping it drops every task of the replica at once,
/// without any wind-down: its sockets and database connections close as in a crash.
#[derive(Debug)]
struct ReplicaRuntime(Option<tokio::runtime::Runtime>);

impl Drop for ReplicaRuntime {
    fn drop(&mut self) {
        if let Some(runtime) = self.0.take() {
            runtime.shutdown_background();
        }
    }
}

/// Starts a proxy replica on `db` in a runtime of its own, so that [`TestProxy::kill`] can
/// crash it (no graceful shutdown, nothing more committed) while the test goes on.
pub async fn spawn_replica(db: TestDatabase, tweak: impl FnOnce(&mut Config)) -> TestProxy {
    let mut config = test_config(&db);
    tweak(&mut config);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a replica runtime");
    let (ready, started) = tokio::sync::oneshot::channel();
    let task = runtime.spawn(async move {
        let app = Application::build(config).await.expect("the replica starts");
        let _ = ready.send((app.port(), app.shutdown_handle(), app.state().clone()));
        app.run_until_stopped().await
    });
    let (port, shutdown, state) = started.await.expect("the replica reports its port");
    TestProxy::started(db, (port, shutdown, state), task, Some(ReplicaRuntime(Some(runtime))))
}

/// A session's id and token, and the key of one participant (`Hello.key`, and the
/// `x-penmesh-key` header of the mesh calls): connections made with the same `TestSession` are
/// the same participant (a reconnect resumes its strokes); [`TestSession::stranger`] is another
/// participant of the same session.
#[derive(Debug, Clone)]
pub struct TestSession {
    pub session: uuid::Uuid,
    pub token: String,
    pub key: String,
}

impl TestSession {
    pub fn new(session: uuid::Uuid, token: String) -> TestSession {
        TestSession { session, token, key: new_key() }
    }

    /// Another participant of the session: the same token, a key of its own.
    pub fn stranger(&self) -> TestSession {
        TestSession { key: new_key(), ..self.clone() }
    }
}

/// A fresh participant key: 32 hex digits, 128 random bits.
pub fn new_key() -> String {
    format!("{:032x}", rand::random::<u128>())
}

/// Starts the proxy with test settings on a fresh database.
pub async fn spawn_proxy() -> TestProxy {
    spawn_proxy_with(|_| {}).await
}

/// Starts the proxy on a fresh database after `tweak` adjusts the settings.
pub async fn spawn_proxy_with(tweak: impl FnOnce(&mut Config)) -> TestProxy {
    spawn_proxy_on(TestDatabase::fresh().await, tweak).await
}

/// Starts the proxy on `db` (for example again after a shutdown).
pub async fn spawn_proxy_on(db: TestDatabase, tweak: impl FnOnce(&mut Config)) -> TestProxy {
    spawn_faulty_proxy_on(db, None, tweak).await
}

/// Starts the proxy on `db` with `faults` injected into its writer's transactions.
pub async fn spawn_faulty_proxy_on(
    db: TestDatabase,
    faults: Option<Arc<penmesh_proxy::CommitFaults>>,
    tweak: impl FnOnce(&mut Config),
) -> TestProxy {
    let mut config = test_config(&db);
    tweak(&mut config);
    let app = Application::build_with_faults(config, faults).await.expect("the proxy starts");
    let started = (app.port(), app.shutdown_handle(), app.state().clone());
    let task = tokio::spawn(app.run_until_stopped());
    TestProxy::started(db, started, task, None)
}

impl TestProxy {
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.address)
    }

    pub async fn create_session(&self) -> TestSession {
        let response =
            self.http.post(self.url("/v1/sessions")).send().await.expect("POST /v1/sessions");
        assert_eq!(response.status(), 201);
        let body: serde_json::Value = response.json().await.unwrap();
        TestSession::new(
            body["session"].as_str().unwrap().parse().unwrap(),
            body["token"].as_str().unwrap().to_string(),
        )
    }

    /// `PUT /v1/strokes/{stroke}/mesh` of `glb` with the session's token and its participant's
    /// key.
    pub fn put_mesh(
        &self,
        session: &TestSession,
        stroke: StrokeId,
        glb: Vec<u8>,
    ) -> reqwest::RequestBuilder {
        self.http
            .put(self.url(&format!("/v1/strokes/{stroke}/mesh")))
            .bearer_auth(&session.token)
            .header(KEY_HEADER, &session.key)
            .header("content-type", "model/gltf-binary")
            .body(glb)
    }

    /// `POST /v1/strokes/{stroke}/mesh/build` with the session's token and its participant's
    /// key.
    pub fn build_mesh(&self, session: &TestSession, stroke: StrokeId) -> reqwest::RequestBuilder {
        self.http
            .post(self.url(&format!("/v1/strokes/{stroke}/mesh/build")))
            .bearer_auth(&session.token)
            .header(KEY_HEADER, &session.key)
    }

    /// GET with the session's bearer token.
    pub fn get(&self, path: &str, session: &TestSession) -> reqwest::RequestBuilder {
        self.http.get(self.url(path)).bearer_auth(&session.token)
    }

    /// GET a JSON body, asserting 200.
    pub async fn get_json(&self, path: &str, session: &TestSession) -> serde_json::Value {
        let response = self.get(path, session).send().await.unwrap();
        assert_eq!(response.status(), 200, "GET {path}");
        response.json().await.unwrap()
    }

    /// A done stroke of `n` samples drawn by `session`'s participant.
    pub async fn done_stroke(&self, session: &TestSession, n: usize) -> StrokeId {
        let mut ws = self.connect(session).await;
        ws.hello(vec![]).await;
        let stroke = uuid::Uuid::new_v4();
        draw_stroke(&mut ws, stroke, &stroke_samples(n), 500).await;
        stroke
    }

    /// `POST /v1/strokes/{source}/duplicate` as `who` (its key) with `body`: the status and
    /// the JSON answer.
    pub async fn duplicate(
        &self,
        who: &TestSession,
        source: StrokeId,
        body: serde_json::Value,
    ) -> (u16, serde_json::Value) {
        let response = self
            .http
            .post(self.url(&format!("/v1/strokes/{source}/duplicate")))
            .bearer_auth(&who.token)
            .header(KEY_HEADER, &who.key)
            .json(&body)
            .send()
            .await
            .unwrap();
        let status = response.status().as_u16();
        (status, response.json().await.unwrap_or(serde_json::Value::Null))
    }

    /// A model whose print outlasts a request timeout of 1 s: a 2,000-sample stroke drawn by
    /// `session`'s participant and 40 duplicates of it, side by side and crossing. Returns the
    /// stroke.
    pub async fn slow_print_model(&self, session: &TestSession) -> StrokeId {
        let source = self.done_stroke(session, 2_000).await;
        for i in 0..40 {
            let mut m = *penmesh::Placement::IDENTITY.matrix();
            (m[12], m[13]) = (f64::from(i % 8) * 40.0, f64::from(i / 8) * 40.0);
            let body = serde_json::json!({"placement": {"matrix": m}});
            let (status, answer) = self.duplicate(session, source, body).await;
            assert_eq!(status, 201, "{answer}");
        }
        source
    }

    /// The stroke list entry for `stroke`.
    pub async fn stroke_info(&self, session: &TestSession, stroke: StrokeId) -> serde_json::Value {
        let list =
            self.get_json(&format!("/v1/sessions/{}/strokes", session.session), session).await;
        list["strokes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["id"] == stroke.to_string())
            .cloned()
            .unwrap_or_else(|| panic!("stroke {stroke} not listed: {list}"))
    }

    /// The committed raw samples of a stroke, through the HTTP API.
    pub async fn raw_samples(&self, session: &TestSession, stroke: StrokeId) -> Vec<Sample> {
        let body = self.get_json(&format!("/v1/strokes/{stroke}/raw"), session).await;
        serde_json::from_value(body["samples"].clone()).unwrap()
    }

    pub async fn connect(&self, session: &TestSession) -> WsClient {
        self.try_connect(session).await.expect("WebSocket connects")
    }

    /// A connection that has said hello and begun `stroke` (its begin acknowledged).
    pub async fn drawing(&self, session: &TestSession, stroke: StrokeId) -> WsClient {
        let mut ws = self.connect(session).await;
        ws.hello(vec![]).await;
        ws.begin(stroke).await;
        ws.wait_ack(stroke, 0).await;
        ws
    }

    pub async fn try_connect(
        &self,
        session: &TestSession,
    ) -> Result<WsClient, tokio_tungstenite::tungstenite::Error> {
        WsClient::try_connect(self.port, session).await
    }

    /// Connects with a raw URL path and query (for auth tests).
    pub async fn try_connect_path(
        &self,
        path_and_query: &str,
    ) -> Result<WsClient, tokio_tungstenite::tungstenite::Error> {
        let url = format!("ws://127.0.0.1:{}{path_and_query}", self.port);
        let (ws, _) = tokio_tungstenite::connect_async(url).await?;
        Ok(WsClient { ws, json: false, key: Some(new_key()) })
    }

    /// Triggers shutdown (as SIGTERM would) without waiting.
    pub fn trigger_shutdown(&self) {
        self.shutdown.cancel();
    }

    /// Shuts down and waits for the application to stop; returns the database.
    pub async fn stop(self) -> TestDatabase {
        self.shutdown.cancel();
        tokio::time::timeout(TIMEOUT, self.task)
            .await
            .expect("the proxy stops within the timeout")
            .expect("the proxy task does not panic")
            .expect("the proxy stops cleanly");
        self.db
    }

    /// Crashes a replica started by [`spawn_replica`]: every task stops where it is, nothing
    /// is flushed. Returns the database.
    pub fn kill(mut self) -> TestDatabase {
        assert!(self.runtime.is_some(), "only a replica started by spawn_replica can be killed");
        self.runtime.take();
        self.db
    }

    /// Prometheus text of `/metrics`.
    pub async fn metrics(&self) -> String {
        self.http.get(self.url("/metrics")).send().await.unwrap().text().await.unwrap()
    }
}

/// A WebSocket client speaking the protocol in binary (default) or JSON.
#[derive(Debug)]
pub struct WsClient {
    pub ws: WebSocketStream<MaybeTlsStream<TcpStream>>,
    pub json: bool,
    /// What [`WsClient::hello`] sends as `Hello.key`: the session's participant's, from
    /// [`TestProxy::connect`].
    pub key: Option<String>,
}

/// Is `msg` a session event (of other participants) rather than an answer to this client?
pub fn is_session_event(msg: &ServerMessage) -> bool {
    matches!(
        msg,
        ServerMessage::PeerJoined(_)
            | ServerMessage::PeerLeft(_)
            | ServerMessage::PeerStrokeBegin(_)
            | ServerMessage::PeerRetained(_)
            | ServerMessage::PeerStrokeDone(_)
            | ServerMessage::PeerMesh(_)
            | ServerMessage::PeerRenamed(_)
            | ServerMessage::PeerStrokes(_)
            | ServerMessage::PeerPlacement(_)
            | ServerMessage::Synced(_)
    )
}

/// What came in on a socket.
#[derive(Debug, Clone, PartialEq)]
pub enum Incoming {
    Message(ServerMessage),
    /// A close frame with its code and reason, or the stream ending.
    Closed(Option<(u16, String)>),
}

/// The request that opens the session's WebSocket on a proxy listening on `port` of this host,
/// with the session's token.
pub fn ws_request(
    port: u16,
    session: &TestSession,
) -> tokio_tungstenite::tungstenite::handshake::client::Request {
    let mut request = format!("ws://127.0.0.1:{port}/v1/sessions/{}/ws", session.session)
        .into_client_request()
        .unwrap();
    request
        .headers_mut()
        .insert("authorization", format!("Bearer {}", session.token).parse().unwrap());
    request
}

impl WsClient {
    /// Connects to the session's WebSocket on a proxy listening on `port` of this host.
    pub async fn try_connect(
        port: u16,
        session: &TestSession,
    ) -> Result<WsClient, tokio_tungstenite::tungstenite::Error> {
        let (ws, _) = tokio_tungstenite::connect_async(ws_request(port, session)).await?;
        Ok(WsClient { ws, json: false, key: Some(session.key.clone()) })
    }

    pub fn json(mut self) -> WsClient {
        self.json = true;
        self
    }

    pub async fn send(&mut self, msg: &ClientMessage) {
        let frame = if self.json {
            Message::Text(encode_client_json(msg).into())
        } else {
            Message::Binary(encode_client(msg).into())
        };
        self.ws.send(frame).await.expect("send");
    }

    pub async fn send_text(&mut self, text: &str) {
        self.ws.send(Message::Text(text.to_string().into())).await.expect("send text");
    }

    pub async fn send_binary(&mut self, bytes: Vec<u8>) {
        self.ws.send(Message::Binary(bytes.into())).await.expect("send binary");
    }

    /// The next protocol message or the close, skipping WebSocket pings and the session's
    /// events ([`is_session_event`]), so single-user tests read only their own conversation.
    pub async fn next(&mut self) -> Incoming {
        self.next_filtered(false).await
    }

    /// The next protocol message or the close, the session's events included.
    pub async fn next_any(&mut self) -> Incoming {
        self.next_filtered(true).await
    }

    /// The next protocol message, the session's events included; panics on a close.
    pub async fn recv_any(&mut self) -> ServerMessage {
        match self.next_any().await {
            Incoming::Message(msg) => msg,
            Incoming::Closed(close) => panic!("connection closed: {close:?}"),
        }
    }

    async fn next_filtered(&mut self, peers: bool) -> Incoming {
        loop {
            let frame =
                tokio::time::timeout(TIMEOUT, self.ws.next()).await.expect("a frame in time");
            match frame {
                None | Some(Err(_)) => return Incoming::Closed(None),
                Some(Ok(Message::Binary(bytes))) => {
                    let msg = decode_server(&bytes, usize::MAX).expect("server binary decodes");
                    if peers || !is_session_event(&msg) {
                        return Incoming::Message(msg);
                    }
                }
                Some(Ok(Message::Text(text))) => {
                    let msg = decode_server_json(&text, usize::MAX).expect("server JSON decodes");
                    if peers || !is_session_event(&msg) {
                        return Incoming::Message(msg);
                    }
                }
                Some(Ok(Message::Close(frame))) => {
                    return Incoming::Closed(
                        frame.map(|f| (u16::from(f.code), f.reason.to_string())),
                    );
                }
                Some(Ok(_)) => continue,
            }
        }
    }

    /// The next frame's raw form: `true` for binary.
    pub async fn next_is_binary(&mut self) -> (bool, ServerMessage) {
        loop {
            match tokio::time::timeout(TIMEOUT, self.ws.next()).await.expect("a frame in time") {
                Some(Ok(Message::Binary(bytes))) => {
                    let msg = decode_server(&bytes, usize::MAX).unwrap();
                    if !is_session_event(&msg) {
                        return (true, msg);
                    }
                }
                Some(Ok(Message::Text(text))) => {
                    let msg = decode_server_json(&text, usize::MAX).unwrap();
                    if !is_session_event(&msg) {
                        return (false, msg);
                    }
                }
                Some(Ok(Message::Ping(_) | Message::Pong(_))) => continue,
                other => panic!("expected a message, got {other:?}"),
            }
        }
    }

    /// The next protocol message; panics on a close.
    pub async fn recv(&mut self) -> ServerMessage {
        match self.next().await {
            Incoming::Message(msg) => msg,
            Incoming::Closed(close) => panic!("connection closed: {close:?}"),
        }
    }

    /// Messages until one satisfies `pred` (returned), collecting the others.
    pub async fn recv_until(
        &mut self,
        mut pred: impl FnMut(&ServerMessage) -> bool,
    ) -> (ServerMessage, Vec<ServerMessage>) {
        let mut others = Vec::new();
        loop {
            let msg = self.recv().await;
            if pred(&msg) {
                return (msg, others);
            }
            others.push(msg);
        }
    }

    /// The next `Error`, skipping other messages; asserts its code.
    pub async fn expect_error(&mut self, code: ErrorCode) -> ErrorMessage {
        let (msg, _) = self.recv_until(|m| matches!(m, ServerMessage::Error(_))).await;
        let ServerMessage::Error(err) = msg else { unreachable!() };
        assert_eq!(err.code, code, "unexpected error: {err:?}");
        err
    }

    /// Waits for the close (skipping messages); returns its code.
    pub async fn expect_close(&mut self) -> Option<u16> {
        loop {
            match self.next().await {
                Incoming::Closed(close) => return close.map(|c| c.0),
                Incoming::Message(_) => continue,
            }
        }
    }

    pub async fn hello(&mut self, resume: Vec<StrokeId>) -> Welcome {
        self.send(&ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-e2e".into(),
            name: None,
            resume,
            key: self.key.clone(),
        }))
        .await;
        match self.recv().await {
            ServerMessage::Welcome(welcome) => welcome,
            other => panic!("expected welcome, got {other:?}"),
        }
    }

    pub async fn begin(&mut self, stroke: StrokeId) {
        self.send(&ClientMessage::StrokeBegin(StrokeBegin {
            stroke,
            brush: Default::default(),
            device: Some("synth:e2e".into()),
            params: None,
            placement: None,
            solid: None,
        }))
        .await;
    }

    pub async fn points(&mut self, stroke: StrokeId, seq: u64, points: &[Sample]) {
        self.send(&ClientMessage::Points(Points {
            stroke,
            seq,
            points: PointBatch(points.to_vec()),
        }))
        .await;
    }

    pub async fn end(&mut self, stroke: StrokeId, n_points: u64) {
        self.send(&ClientMessage::StrokeEnd(StrokeEnd { stroke, n_points })).await;
    }

    /// Waits until `Ack {stroke, upto_seq >= upto}`; returns the retained samples seen meanwhile
    /// as `(first, points)` pairs.
    pub async fn wait_ack(&mut self, stroke: StrokeId, upto: u64) -> Vec<(u64, Vec<Sample>)> {
        let mut retained = Vec::new();
        loop {
            match self.recv().await {
                ServerMessage::Ack(ack) if ack.stroke == stroke && ack.upto_seq >= upto => {
                    return retained;
                }
                ServerMessage::Retained(r) if r.stroke == stroke => {
                    retained.push((r.first, r.points.0))
                }
                ServerMessage::Error(err) => panic!("unexpected error: {err:?}"),
                _ => {}
            }
        }
    }
}

/// Collects `(first, points)` pieces into one simplified stroke, checking there is no gap
/// and that repeats agree.
pub fn assemble_retained(pieces: &[(u64, Vec<Sample>)]) -> Vec<Sample> {
    let mut out: Vec<Sample> = Vec::new();
    for (first, points) in pieces {
        let first = *first as usize;
        assert!(first <= out.len(), "gap in retained: {first} after {}", out.len());
        for (i, s) in points.iter().enumerate() {
            if first + i < out.len() {
                assert_eq!(out[first + i], *s, "repeated retained sample {} differs", first + i);
            } else {
                out.push(*s);
            }
        }
    }
    out
}

/// A deterministic pen stroke of `n` samples: a wavy line with changing pressure, on the
/// binary codec's quantisation grid (so binary and JSON clients send the same values).
pub fn stroke_samples(n: usize) -> Vec<Sample> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            let s = Sample::new(
                f * 1.5,
                20.0 * (f / 9.0).sin() + 3.0 * (f / 2.3).cos(),
                f * 5.0,
                0.5 + 0.3 * (f / 17.0).sin(),
            );
            penmesh::protocol::quantize_sample(&s)
        })
        .collect()
}

/// The streamed result a proxy must give for `samples`: the batch simplification.
pub fn batch_simplified(samples: &[Sample]) -> Vec<Sample> {
    penmesh::simplify(samples, &penmesh::AcutsParams::default())
        .into_iter()
        .map(|i| samples[i])
        .collect()
}

/// Sends a whole stroke in batches and waits for `StrokeDone`; returns the retained samples
/// streamed back and the `StrokeDone` `n_retained`.
pub async fn draw_stroke(
    ws: &mut WsClient,
    stroke: StrokeId,
    samples: &[Sample],
    batch: usize,
) -> (Vec<Sample>, u64) {
    ws.begin(stroke).await;
    let mut pieces = ws.wait_ack(stroke, 0).await;
    for (i, chunk) in samples.chunks(batch).enumerate() {
        ws.points(stroke, (i * batch) as u64, chunk).await;
    }
    pieces.extend(ws.wait_ack(stroke, samples.len() as u64).await);
    ws.end(stroke, samples.len() as u64).await;
    loop {
        match ws.recv().await {
            ServerMessage::Retained(r) if r.stroke == stroke => pieces.push((r.first, r.points.0)),
            ServerMessage::StrokeDone(done) if done.stroke == stroke => {
                assert_eq!(done.url, format!("/v1/strokes/{stroke}/simplified"));
                return (assemble_retained(&pieces), done.n_retained);
            }
            ServerMessage::Error(err) => panic!("unexpected error: {err:?}"),
            _ => {}
        }
    }
}

/// Counts rows straight from the database (to check what was stored, bypassing the proxy).
pub async fn count_rows(db: &TestDatabase, sql: &str) -> i64 {
    sqlx::any::install_default_drivers();
    let url = if db.is_postgres() { db.url.clone() } else { format!("{}?mode=ro", db.url) };
    let pool = sqlx::any::AnyPoolOptions::new().max_connections(1).connect(&url).await.unwrap();
    let n: i64 = sqlx::query_scalar(sql).fetch_one(&pool).await.unwrap();
    pool.close().await;
    n
}

/// Runs one statement straight on the database, behind the proxy's back (what a replica of
/// another release, or an operator, may do).
pub async fn execute_sql(db: &TestDatabase, sql: &str) {
    sqlx::any::install_default_drivers();
    let pool = sqlx::any::AnyPoolOptions::new().max_connections(1).connect(&db.url).await.unwrap();
    sqlx::query(sql).execute(&pool).await.unwrap();
    pool.close().await;
}

/// A GLB (binary glTF 2.0, written by `penmesh` as the client writes its meshes) of one
/// indexed triangle list of `vertices` positions and `indices` indices, all zero: enough for
/// the proxy's upload checks, which read the counts and check them against the buffers.
pub fn minimal_glb(vertices: u64, indices: u64) -> Vec<u8> {
    let mesh = penmesh::StrokeMesh {
        positions: vec![[0.0; 3]; vertices as usize],
        normals: vec![[0.0, 0.0, 1.0]; vertices as usize],
        indices: vec![0; indices as usize],
    };
    let meta = penmesh::GlbMeta {
        stroke: uuid::Uuid::nil(),
        author: "penmesh-e2e".into(),
        brush: penmesh::Brush::default(),
    };
    penmesh::stroke_glb(&mesh, &meta, &penmesh::GlbOptions::default())
}

/// A GLB of `vertices` positions and normals, not compressed: about 24 bytes a vertex (a mesh
/// of a chosen size).
pub fn plain_glb(vertices: usize) -> Vec<u8> {
    let mesh = penmesh::StrokeMesh {
        positions: (0..vertices).map(|i| [i as f32, 1.0, 2.0]).collect(),
        normals: vec![[0.0, 0.0, 1.0]; vertices],
        indices: vec![0, 1, 2],
    };
    let meta = penmesh::GlbMeta {
        stroke: uuid::Uuid::nil(),
        author: "penmesh-e2e".into(),
        brush: penmesh::Brush::default(),
    };
    let options = penmesh::GlbOptions::default().encoding(penmesh::GlbEncoding::Plain);
    penmesh::stroke_glb(&mesh, &meta, &options)
}
