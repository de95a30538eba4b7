//! A model storm (issues 37 and 39): twenty people model in one session at the same moment.
//! Each joins at once with the native client and draws real strokes on a work plane of its own
//! (`stroke_begin.placement`); then all at once they move, turn, scale, mirror and duplicate
//! their own strokes, over the WebSocket (three `set_placement`s sent back to back, answered in
//! order) and over HTTP (`PUT …/placement`, `POST …/duplicate`) at the same time; two of them
//! try to move another's stroke (refused, nothing changes, they go on modelling and drawing on
//! the same connection) and two import a GLB exported from another session. At the end every
//! client's live view, a late joiner's, the strokes list and each stroke's placement history
//! hold exactly what the drawers had acknowledged, bit for bit and in order; every import is
//! there whole; the proxy answered no request with a 5xx. Three watchers join mid-storm. Two
//! replicas with PostgreSQL (`PENMESH_TEST_POSTGRES_URL`), one proxy on SQLite. Each view is
//! told each placement once, never an older one after a newer one: the proxy orders a stroke's
//! placements by their row ids (docs/reliability.md, "A model storm").

use std::collections::{BTreeMap, BTreeSet};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures_util::StreamExt;
use penmesh::Placement;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, KEY_HEADER, PROTOCOL_VERSION, PlacementHistory, ServerMessage,
    SetPlacement, StrokeBegin, StrokeEnd, StrokeId, StrokeList, decode_server, quantize_sample,
};
use penmesh_client::draw_options::DrawOptions;
use penmesh_client::endpoint::Endpoint;
use penmesh_client::input::{Pacing, ReplaySource};
use penmesh_e2e::{TestDatabase, TestProxy, TestSession, WsClient, spawn_proxy_on, spawn_replica};
use tokio_tungstenite::tungstenite::Message;
use uuid::Uuid;

use crate::{internal_errors, real_strokes};

/// People modelling at once, the real strokes each draws first, and the rounds of changes each
/// then makes (a round: three changes of one stroke on the socket while two of another go over
/// HTTP, and every other round a duplicate).
const N_CLIENTS: usize = 20;
const STROKES_PER_CLIENT: usize = 3;
const ROUNDS: usize = 10;
/// Who tries to move another's stroke (in round 2), and who imports a GLB (in round 1).
const INTRUDERS: [usize; 2] = [0, 7];
const IMPORTERS: [usize; 2] = [3, 12];
/// Strokes of the session the GLB is exported from.
const N_EXPORTED: usize = 4;
/// How long the last events may take to reach every client once all changes are acknowledged.
const SETTLE: Duration = Duration::from_secs(20);
/// When each watcher joins, after the modelling began, in ms.
const WATCHERS_JOIN_MS: [u64; 3] = [100, 400, 1200];

mod placements;
use placements::*;

/// One placement a stroke had: its bits, and why (`begin`, `set`, `duplicate`).
type Entry = (Exact, &'static str);

/// A stroke as its drawer knows it: whose, and every placement the proxy acknowledged, in
/// order (the last is its current one).
#[derive(Debug, Clone)]
struct Acknowledged {
    drawer: Uuid,
    placements: Vec<Entry>,
}

/// What one connection was told of the session's placements, checked as it arrives.
#[derive(Debug, Default)]
struct Seen {
    /// Every stroke it heard of, with the placements it was told, in order.
    strokes: BTreeMap<StrokeId, Vec<Exact>>,
    /// Times the connection fell behind and was resynced.
    lagged: usize,
    synced: usize,
    /// The client's number, for the messages.
    who: usize,
}

impl Seen {
    fn apply(&mut self, msg: &ServerMessage) {
        match msg {
            ServerMessage::PeerStrokes(strokes) => {
                strokes.messages().iter().for_each(|m| self.apply(m))
            }
            ServerMessage::PeerStrokeBegin(b) => {
                assert!(self.strokes.insert(b.stroke, Vec::new()).is_none(), "begun twice");
            }
            ServerMessage::PeerPlacement(p) => {
                let who = self.who;
                let told = self.strokes.get_mut(&p.stroke);
                let told = told.unwrap_or_else(|| {
                    panic!("client {who}: told a placement of {} before the stroke", p.stroke)
                });
                told.push(bits(&p.placement));
            }
            ServerMessage::Synced(_) => self.synced += 1,
            ServerMessage::Error(e) if e.code == ErrorCode::Lagged => self.lagged += 1,
            ServerMessage::Error(e) if e.code == ErrorCode::Internal => {
                panic!("client {}: {e:?}", self.who)
            }
            _ => {}
        }
    }
}

/// One person modelling: the socket it models on, its HTTP identity, and its strokes.
struct Modeller {
    i: usize,
    ws: WsClient,
    me: TestSession,
    participant: Uuid,
    seen: Seen,
    /// Its strokes and their acknowledged placements.
    mine: BTreeMap<StrokeId, Acknowledged>,
    /// Strokes drawn on this very socket: the proxy tells it nothing of them but its answers.
    drawn_here: BTreeSet<StrokeId>,
    /// The strokes it imported, with their samples in the file.
    imported: BTreeMap<StrokeId, u64>,
    n_changes: usize,
}

impl Modeller {
    async fn join(proxy: &TestProxy, me: TestSession, i: usize) -> Modeller {
        let mut ws = proxy.connect(&me).await;
        let participant = penmesh_proxy::participant_id(me.session, &me.key);
        ws.send(&ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-e2e modeller".into(),
            name: Some(format!("modeller {i}")),
            resume: vec![],
            key: Some(me.key.clone()),
        }))
        .await;
        let mut m = Modeller {
            i,
            ws,
            me,
            participant,
            seen: Seen { who: i, ..Seen::default() },
            mine: BTreeMap::new(),
            drawn_here: BTreeSet::new(),
            imported: BTreeMap::new(),
            n_changes: 0,
        };
        while m.seen.synced == 0 {
            m.recv().await;
        }
        m
    }

    /// The next message, recorded.
    async fn recv(&mut self) -> ServerMessage {
        let msg = self.ws.recv_any().await;
        self.seen.apply(&msg);
        msg
    }

    /// Waits at `barrier`, reading (and recording) what the session tells meanwhile, as a page
    /// does while its person looks on.
    async fn wait_reading(&mut self, barrier: &tokio::sync::Barrier) {
        let wait = barrier.wait();
        tokio::pin!(wait);
        loop {
            tokio::select! {
                _ = &mut wait => return,
                frame = self.ws.ws.next() => {
                    let Some(msg) = decode(frame) else { continue };
                    self.seen.apply(&msg);
                    if let ServerMessage::Error(e) = &msg {
                        assert_eq!(e.code, ErrorCode::Lagged, "client {}: {e:?}", self.i);
                    }
                }
            }
        }
    }

    /// The placements this connection is to be told of `stroke`, in order: all of them but a
    /// first one at the identity (never told) and, for a stroke drawn on this socket, its
    /// begin (the drawer has it).
    fn to_be_told(&self, stroke: &StrokeId, a: &Acknowledged) -> Vec<Exact> {
        let mut told: Vec<Exact> = a.placements.iter().map(|(p, _)| *p).collect();
        if self.drawn_here.contains(stroke) || told[0] == bits(&Placement::IDENTITY) {
            told.remove(0);
        }
        told
    }

    fn current(&self, stroke: StrokeId) -> Placement {
        self.mine[&stroke].placements.last().expect("a placement").0.0
    }

    /// The next `changes` of `stroke`, each from the one before.
    fn plan(&mut self, stroke: StrokeId, changes: &[Change]) -> Vec<Placement> {
        let mut at = self.current(stroke);
        let mut out = Vec::new();
        for &change in changes {
            self.n_changes += 1;
            at = changed(&at, change, self.n_changes);
            out.push(at);
        }
        out
    }

    fn acknowledge(&mut self, stroke: StrokeId, placement: &Placement, cause: &'static str) {
        let drawer = self.participant;
        let entry = (bits(placement), cause);
        match self.mine.get_mut(&stroke) {
            Some(known) => known.placements.push(entry),
            None => {
                self.mine.insert(stroke, Acknowledged { drawer, placements: vec![entry] });
            }
        }
    }

    /// One round: `set_placement`s of one stroke back to back on the socket while HTTP places
    /// another, duplicates (every other round), imports (an importer, round 1) or tries to
    /// place another's stroke (an intruder, round 2).
    async fn round(&mut self, r: usize, ctx: &Ctx) {
        let own: Vec<StrokeId> = self.mine.keys().copied().collect();
        let (on_socket, over_http) = (own[(2 * r) % own.len()], own[(2 * r + 1) % own.len()]);
        let socket = self.plan(on_socket, &[Change::Move, Change::Turn, Change::Mirror]);
        let http = self.plan(over_http, &[Change::Scale, Change::Move]);
        let duplicate = (r % 2 == 1).then(|| {
            let source = own[r % own.len()];
            let at = self.plan(source, &[Change::Move]).pop().unwrap();
            (source, Uuid::new_v4(), at)
        });
        let intrude = (r == 2 && INTRUDERS.contains(&self.i)).then(|| {
            let victim = ctx.first_stroke_of((self.i + 5) % N_CLIENTS);
            (victim, changed(&plane(self.i), Change::Move, 999))
        });
        let import = r == 1 && IMPORTERS.contains(&self.i);

        // No wait for what it did to that stroke over HTTP (on another replica) to reach its
        // socket: the proxy tells the socket those placements before its answers.
        let i = self.i;
        let proxy = ctx.http_proxy_of(i);
        let Modeller { ws, seen, me, .. } = self;
        let (_, (imported, duplicated)) =
            tokio::join!(socket_changes(ws, seen, on_socket, &socket, intrude), async {
                for p in &http {
                    let (status, why) = put_placement(proxy, me, over_http, p).await;
                    assert_eq!(status, 204, "client {i}: PUT placement: {why}");
                }
                if let Some((victim, p)) = intrude {
                    let (status, why) = put_placement(proxy, me, victim, &p).await;
                    assert_eq!(status, 403, "client {i}: another's stroke over HTTP: {why}");
                }
                let mut duplicated = None;
                if let Some((source, id, p)) = duplicate {
                    duplicate_stroke(proxy, me, source, id, &p).await;
                    duplicated = Some((id, p));
                }
                let imported =
                    if import { Some(import_glb(proxy, me, &ctx.glb).await) } else { None };
                (imported, duplicated)
            });
        for p in &socket {
            self.acknowledge(on_socket, p, "set");
        }
        for p in &http {
            self.acknowledge(over_http, p, "set");
        }
        if let Some((id, p)) = duplicated {
            self.acknowledge(id, &p, "duplicate");
        }
        for (stroke, matrix, n_samples) in imported.into_iter().flatten() {
            self.acknowledge(stroke, &placement(matrix), "begin");
            self.imported.insert(stroke, n_samples);
        }
        if intrude.is_some() {
            // Refused twice; the connection goes on: a new real stroke drawn on it.
            let stroke = Uuid::new_v4();
            let on = changed(&plane(self.i), Change::Turn, 500);
            self.seen.strokes.insert(stroke, Vec::new());
            draw_on_socket(&mut self.ws, &mut self.seen, stroke, &ctx.extra_stroke(self.i), on)
                .await;
            self.drawn_here.insert(stroke);
            self.acknowledge(stroke, &on, "begin");
            // Its mesh built by the proxy, as the page asks for it.
            let built = ctx.http_proxy_of(self.i).build_mesh(&self.me, stroke).send().await;
            assert_eq!(built.unwrap().status(), 200, "client {}: its mesh built", self.i);
        }
    }

    /// Reads until this connection has been told the last placement of every stroke in
    /// `expected`; fails naming what is missing after [`SETTLE`].
    async fn settle(&mut self, expected: &BTreeMap<StrokeId, Acknowledged>) {
        let deadline = tokio::time::Instant::now() + SETTLE;
        loop {
            let missing: Vec<StrokeId> = expected
                .iter()
                .filter(|(id, a)| {
                    let told = self.seen.strokes.get(id).map(|told| told.last());
                    told != Some(self.to_be_told(id, a).last())
                })
                .map(|(id, _)| *id)
                .collect();
            if missing.is_empty() {
                return;
            }
            match tokio::time::timeout_at(deadline, self.ws.ws.next()).await {
                Ok(frame) => decode(frame).iter().for_each(|msg| self.seen.apply(msg)),
                Err(_) => {
                    let stroke = missing[0];
                    let wanted = self.to_be_told(&stroke, &expected[&stroke]);
                    let told = self.seen.strokes.get(&stroke).cloned().unwrap_or_default();
                    let last = told.last().and_then(|p| wanted.iter().position(|w| w == p));
                    panic!(
                        "client {}: {} strokes never reached their last placement; {stroke} \
                         was told {} of its {} placements, the last told being its number \
                         {last:?}",
                        self.i,
                        missing.len(),
                        told.len(),
                        wanted.len(),
                    )
                }
            }
        }
    }
}

/// A frame the proxy sent, decoded (`None`: a WebSocket ping or pong); a closed connection
/// fails the test.
fn decode(
    frame: Option<Result<Message, tokio_tungstenite::tungstenite::Error>>,
) -> Option<ServerMessage> {
    match frame {
        Some(Ok(Message::Binary(bytes))) => Some(decode_server(&bytes, usize::MAX).unwrap()),
        Some(Ok(Message::Ping(_) | Message::Pong(_))) => None,
        other => panic!("the connection ended: {other:?}"),
    }
}

/// Sends `changes` of `stroke` back to back (and, for an intruder, a change of another's
/// stroke among them); waits for each answer, in the order sent, and for the refusal.
async fn socket_changes(
    ws: &mut WsClient,
    seen: &mut Seen,
    stroke: StrokeId,
    changes: &[Placement],
    intrude: Option<(StrokeId, Placement)>,
) {
    for (k, p) in changes.iter().enumerate() {
        ws.send(&ClientMessage::SetPlacement(SetPlacement { stroke, placement: *p })).await;
        if k == 0
            && let Some((victim, p)) = intrude
        {
            ws.send(&ClientMessage::SetPlacement(SetPlacement { stroke: victim, placement: p }))
                .await;
        }
    }
    let sent: Vec<Exact> = changes.iter().map(bits).collect();
    let (mut answered, mut refused) = (0, intrude.is_none());
    while answered < sent.len() || !refused {
        let msg = ws.recv_any().await;
        seen.apply(&msg);
        match msg {
            ServerMessage::PeerPlacement(p) if p.stroke == stroke => {
                let got = bits(&p.placement);
                if let Some(later) = sent[answered..].iter().position(|s| *s == got) {
                    assert_eq!(
                        later,
                        0,
                        "answer {} of {} came before its turn",
                        answered + later,
                        sent.len()
                    );
                    answered += 1;
                }
                // Else an earlier change told late (one made over HTTP in an earlier round).
            }
            ServerMessage::Error(e) if e.code == ErrorCode::NotOwner && intrude.is_some() => {
                assert_eq!(e.stroke, intrude.map(|(victim, _)| victim), "{e:?}");
                assert!(!refused, "refused twice: {e:?}");
                refused = true;
            }
            ServerMessage::Error(e) if e.code == ErrorCode::Lagged => {}
            ServerMessage::Error(e) => panic!("unexpected error: {e:?}"),
            _ => {}
        }
    }
}

/// Draws `samples` as a new stroke on the work plane `on`, over `ws`, to its `stroke_done`.
async fn draw_on_socket(
    ws: &mut WsClient,
    seen: &mut Seen,
    stroke: StrokeId,
    samples: &[penmesh::Sample],
    on: Placement,
) {
    ws.send(&ClientMessage::StrokeBegin(StrokeBegin {
        stroke,
        brush: Default::default(),
        device: Some("synth:e2e".into()),
        params: None,
        placement: Some(on),
        solid: None,
    }))
    .await;
    for (k, chunk) in samples.chunks(32).enumerate() {
        ws.points(stroke, (k * 32) as u64, chunk).await;
    }
    ws.send(&ClientMessage::StrokeEnd(StrokeEnd { stroke, n_points: samples.len() as u64 })).await;
    loop {
        let msg = ws.recv_any().await;
        seen.apply(&msg);
        match msg {
            ServerMessage::StrokeDone(d) if d.stroke == stroke => return,
            ServerMessage::Error(e) if e.code == ErrorCode::Lagged => {}
            ServerMessage::Error(e) => panic!("drawing after a refusal: {e:?}"),
            _ => {}
        }
    }
}

/// `PUT /v1/strokes/{stroke}/placement` as `who`: the status and the body.
async fn put_placement(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: StrokeId,
    p: &Placement,
) -> (u16, String) {
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{stroke}/placement")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .json(&serde_json::json!({ "matrix": p.matrix() }))
        .send()
        .await
        .unwrap();
    (response.status().as_u16(), response.text().await.unwrap())
}

async fn duplicate_stroke(
    proxy: &TestProxy,
    who: &TestSession,
    source: StrokeId,
    id: StrokeId,
    p: &Placement,
) {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/strokes/{source}/duplicate")))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .json(&serde_json::json!({ "stroke": id, "placement": { "matrix": p.matrix() } }))
        .send()
        .await
        .unwrap();
    let status = response.status();
    assert_eq!(status, 201, "duplicate: {}", response.text().await.unwrap());
}

/// Imports `glb` as `who`: each new stroke with its node's matrix and its number of samples,
/// in the file's order.
async fn import_glb(
    proxy: &TestProxy,
    who: &TestSession,
    glb: &[u8],
) -> Vec<(StrokeId, Matrix, u64)> {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import", who.session)))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .header("content-type", "model/gltf-binary")
        .body(glb.to_vec())
        .send()
        .await
        .unwrap();
    let status = response.status();
    let text = response.text().await.unwrap();
    assert_eq!(status, 201, "import: {text}");
    let imported: penmesh::protocol::Imported = serde_json::from_str(&text).unwrap();
    let file = penmesh::read_scene(glb).unwrap();
    assert_eq!(imported.strokes.len(), file.len(), "every stroke of the file, or none");
    imported
        .strokes
        .iter()
        .zip(&file)
        .map(|(new, read)| {
            assert_eq!(new.source, read.extras.stroke, "in the file's order");
            (new.stroke, read.placement, read.extras.samples.len() as u64)
        })
        .collect()
}

/// Whether a connection that was `told` these placements of a stroke was told `wanted` (what
/// its drawer acknowledged) exactly: the one its history held (or the first, for a stroke made
/// after it joined), then every later one, once each, in order, to the last. Else the number
/// of each placement told (`usize::MAX`: never acknowledged). None to be told, none told.
fn told_in_order(told: &[Exact], wanted: &[Exact]) -> Result<(), Vec<usize>> {
    let at: Vec<usize> =
        told.iter().map(|p| wanted.iter().position(|w| w == p).unwrap_or(usize::MAX)).collect();
    let in_order = at.iter().all(|&k| k < wanted.len())
        && at.windows(2).all(|w| w[1] == w[0] + 1)
        && at.last().copied() == wanted.len().checked_sub(1);
    if in_order { Ok(()) } else { Err(at) }
}

/// What every client shares: the proxies, the session, the strokes and the file.
struct Ctx {
    proxies: Vec<TestProxy>,
    session: TestSession,
    strokes: Vec<penmesh::Stroke>,
    glb: Vec<u8>,
    /// Each client's first stroke, once drawn (the intruders' victims).
    first: Mutex<BTreeMap<usize, StrokeId>>,
}

impl Ctx {
    /// The replica client `i` draws and models on over the socket.
    fn proxy_of(&self, i: usize) -> &TestProxy {
        &self.proxies[i % self.proxies.len()]
    }

    /// The replica it sends its HTTP requests to: the other one, so that what it does over
    /// HTTP reaches its socket through the database's notifications.
    fn http_proxy_of(&self, i: usize) -> &TestProxy {
        &self.proxies[(i + 1) % self.proxies.len()]
    }

    fn first_stroke_of(&self, i: usize) -> StrokeId {
        self.first.lock().unwrap()[&i]
    }

    /// The real strokes client `i` draws with the native client.
    fn strokes_of(&self, i: usize) -> Vec<penmesh::Stroke> {
        (0..STROKES_PER_CLIENT)
            .map(|j| self.strokes[(i * STROKES_PER_CLIENT + j) % self.strokes.len()].clone())
            .collect()
    }

    /// The real stroke an intruder draws on its socket after its refusal, on the codec's grid.
    fn extra_stroke(&self, i: usize) -> Vec<penmesh::Sample> {
        let stroke = &self.strokes[(N_CLIENTS * STROKES_PER_CLIENT + i) % self.strokes.len()];
        let samples: Vec<_> = stroke.samples().iter().map(quantize_sample).collect();
        let kept = penmesh::resample(&samples, penmesh::DEFAULT_RESAMPLE_DISTANCE);
        kept.into_iter().map(|k| samples[k]).collect()
    }
}

/// Draws `strokes` as one person through the native client's live path, on `on`.
async fn draw(
    endpoint: &Endpoint,
    options: &DrawOptions,
    strokes: Vec<penmesh::Stroke>,
) -> anyhow::Result<Vec<penmesh_client::reconstruct::StrokeReport>> {
    let source = ReplaySource::new(options.name.clone(), strokes, Pacing::Fast);
    penmesh_client::live::draw(endpoint, Box::new(source), options).await
}

/// The WebSocket's internal errors: `penmesh_errors_total{code="internal"}`.
fn socket_internal_errors(metrics: &str) -> f64 {
    metrics
        .lines()
        .filter(|l| l.starts_with("penmesh_errors_total") && l.contains("code=\"internal\""))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

/// A GLB exported from a session of its own: real strokes on standing planes, one mirrored.
async fn exported_glb(proxy: &TestProxy, strokes: &[penmesh::Stroke]) -> Vec<u8> {
    let source = proxy.create_session().await;
    let endpoint = Endpoint::new(&proxy.address, source.session, source.token.clone()).unwrap();
    let mut options = DrawOptions::new("exporter");
    options.placement = Some(plane(N_CLIENTS + 1));
    let drawn = draw(&endpoint, &options, strokes.to_vec()).await.expect("the exported strokes");
    let exporter = TestSession { key: options.key.clone(), ..source.clone() };
    let mirrored = changed(&plane(N_CLIENTS + 1), Change::Mirror, 1);
    assert_eq!(put_placement(proxy, &exporter, drawn[1].stroke, &mirrored).await.0, 204);
    let path = format!("/v1/sessions/{}/export?format=glb", source.session);
    let response = proxy.get(&path, &source).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let glb = response.bytes().await.unwrap().to_vec();
    assert_eq!(penmesh::read_scene(&glb).unwrap().len(), strokes.len());
    glb
}

/// Two replicas on one fresh PostgreSQL database with `PENMESH_TEST_POSTGRES_URL`, else one
/// proxy on SQLite.
async fn proxies() -> Vec<TestProxy> {
    let db = TestDatabase::fresh().await;
    if db.is_postgres() {
        vec![spawn_replica(db.clone(), |_| {}).await, spawn_replica(db, |_| {}).await]
    } else {
        vec![spawn_proxy_on(db, |_| {}).await]
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_people_modelling_at_once_see_every_acknowledged_placement_in_order() {
    // Arrange: the proxies, a GLB from another session, and the session.
    let proxies = proxies().await;
    let strokes = real_strokes();
    let glb = exported_glb(&proxies[0], &strokes[strokes.len() - N_EXPORTED..]).await;
    let session = proxies[0].create_session().await;
    let ctx = Arc::new(Ctx { proxies, session, strokes, glb, first: Mutex::default() });
    let errors_before = {
        let metrics = ctx.proxies[0].metrics().await;
        (internal_errors(&metrics), socket_internal_errors(&metrics))
    };

    // Act: all join at once and draw; once all are drawn and listening, all model at once.
    let started = std::time::Instant::now();
    let joined = Arc::new(tokio::sync::Barrier::new(N_CLIENTS));
    // The modellers and the watchers who join while they model.
    let n_waiting = N_CLIENTS + WATCHERS_JOIN_MS.len();
    let drawn = Arc::new(tokio::sync::Barrier::new(n_waiting));
    let modelled = Arc::new(tokio::sync::Barrier::new(n_waiting));
    let everything = Arc::new(Mutex::new(BTreeMap::new()));
    let mut watchers = tokio::task::JoinSet::new();
    for (k, after) in WATCHERS_JOIN_MS.into_iter().enumerate() {
        let (ctx, drawn, modelled) = (ctx.clone(), drawn.clone(), modelled.clone());
        let everything = everything.clone();
        watchers.spawn(async move {
            drawn.wait().await;
            tokio::time::sleep(Duration::from_millis(after)).await;
            let proxy = &ctx.proxies[k % ctx.proxies.len()];
            let mut watcher = Modeller::join(proxy, ctx.session.stranger(), N_CLIENTS + k).await;
            watcher.wait_reading(&modelled).await;
            let expected = everything.lock().unwrap().clone();
            watcher.settle(&expected).await;
            watcher
        });
    }
    let mut clients = tokio::task::JoinSet::new();
    for i in 0..N_CLIENTS {
        let (ctx, joined, drawn, modelled) =
            (ctx.clone(), joined.clone(), drawn.clone(), modelled.clone());
        let everything = everything.clone();
        clients.spawn(async move {
            let proxy = ctx.proxy_of(i);
            let endpoint =
                Endpoint::new(&proxy.address, ctx.session.session, ctx.session.token.clone())
                    .unwrap();
            let mut options = DrawOptions::new(format!("modeller {i}"));
            options.placement = Some(plane(i));
            joined.wait().await;
            let reports = draw(&endpoint, &options, ctx.strokes_of(i))
                .await
                .unwrap_or_else(|e| panic!("client {i} gave up: {e:#}"));
            assert_eq!(reports.len(), STROKES_PER_CLIENT, "client {i}: a report per stroke");
            assert!(reports.iter().all(|r| r.exact), "client {i}: stored as drawn");
            let me = TestSession { key: options.key.clone(), ..ctx.session.clone() };
            let mut modeller = Modeller::join(proxy, me, i).await;
            for report in &reports {
                modeller.acknowledge(report.stroke, &plane(i), "begin");
            }
            ctx.first.lock().unwrap().insert(i, reports[0].stroke);
            modeller.wait_reading(&drawn).await;
            let modelling = std::time::Instant::now();
            for r in 0..ROUNDS {
                modeller.round(r, &ctx).await;
            }
            everything.lock().unwrap().extend(modeller.mine.clone());
            let modelling = modelling.elapsed();
            modeller.wait_reading(&modelled).await;
            let expected = everything.lock().unwrap().clone();
            modeller.settle(&expected).await;
            (modeller, modelling)
        });
    }
    let (mut modellers, mut slowest) = (Vec::new(), Duration::ZERO);
    while let Some(joined) = clients.join_next().await {
        let (modeller, modelling) = joined.expect("a client failed");
        modellers.push(modeller);
        slowest = slowest.max(modelling);
    }
    let watchers = watchers.join_all().await;
    let expected: BTreeMap<StrokeId, Acknowledged> = everything.lock().unwrap().clone();
    eprintln!(
        "model storm: {} clients, {} strokes, {} placements acknowledged; {:.1} s in all, the \
         slowest client's changes {:.1} s",
        N_CLIENTS,
        expected.len(),
        expected.values().map(|a| a.placements.len()).sum::<usize>(),
        started.elapsed().as_secs_f64(),
        slowest.as_secs_f64()
    );

    // Assert: the numbers add up (every change acknowledged, imports whole).
    let n_drawn = N_CLIENTS * STROKES_PER_CLIENT + INTRUDERS.len();
    let n_duplicates = N_CLIENTS * (ROUNDS / 2);
    assert_eq!(expected.len(), n_drawn + n_duplicates + IMPORTERS.len() * N_EXPORTED);
    let n_changes: usize = expected.values().map(|a| a.placements.len() - 1).sum();
    assert_eq!(n_changes, N_CLIENTS * ROUNDS * 5);

    // Every client, and each watcher who joined mid-storm, was told every acknowledged
    // placement of every stroke, in order, to the last.
    for m in modellers.iter().chain(&watchers) {
        let who = match m.i.checked_sub(N_CLIENTS) {
            None => format!("client {}", m.i),
            Some(w) => format!("watcher {w}, who joined mid-storm,"),
        };
        assert_eq!(m.seen.lagged, 0, "{who} fell behind the session's events");
        for (stroke, a) in &expected {
            let told = m.seen.strokes.get(stroke);
            let told = told.unwrap_or_else(|| panic!("{who} was never told of {stroke}"));
            let wanted = m.to_be_told(stroke, a);
            if let Err(at) = told_in_order(told, &wanted) {
                panic!(
                    "{who} was told the placements of {stroke} as numbers {at:?} of its {}",
                    wanted.len()
                );
            }
        }
        assert_eq!(m.seen.strokes.len(), expected.len(), "{who}: strokes never made");
    }

    let imported: BTreeMap<StrokeId, u64> =
        modellers.iter().flat_map(|m| m.imported.clone()).collect();
    assert_eq!(imported.len(), IMPORTERS.len() * N_EXPORTED, "every import whole");

    // A late joiner (on the last replica) is told each stroke's last placement, only that.
    let late = Modeller::join(ctx.proxies.last().unwrap(), ctx.session.stranger(), N_CLIENTS).await;
    for (stroke, a) in &expected {
        let wanted: Vec<Exact> = late.to_be_told(stroke, a).last().into_iter().copied().collect();
        assert_eq!(late.seen.strokes.get(stroke), Some(&wanted), "the late joiner: {stroke}");
    }
    assert_eq!(late.seen.strokes.len(), expected.len(), "the late joiner: strokes never made");

    // The strokes list on every replica: every stroke, its drawer, its last placement.
    for proxy in &ctx.proxies {
        let path = format!("/v1/sessions/{}/strokes", ctx.session.session);
        let list: StrokeList =
            serde_json::from_value(proxy.get_json(&path, &ctx.session).await).unwrap();
        let listed: BTreeMap<StrokeId, (Uuid, Exact)> =
            list.strokes.iter().map(|s| (s.id, (s.participant, bits(&s.placement)))).collect();
        let wanted: BTreeMap<StrokeId, (Uuid, Exact)> = expected
            .iter()
            .map(|(id, a)| (*id, (a.drawer, a.placements.last().unwrap().0)))
            .collect();
        assert_eq!(listed, wanted, "the strokes list");
        for s in &list.strokes {
            assert_eq!(s.status, penmesh::protocol::StrokeStatus::Done, "{}", s.id);
            // Each with its mesh, an imported one with every sample of the file.
            assert!(s.has_mesh, "{} has no mesh", s.id);
            if let Some(n_samples) = imported.get(&s.id) {
                assert_eq!((s.n_points, s.n_retained), (*n_samples, *n_samples), "{}", s.id);
            }
        }
    }

    // Each stroke's placement history: every acknowledged change, in order, by its drawer.
    for (stroke, a) in &expected {
        let proxy = &ctx.proxies[stroke.as_bytes()[0] as usize % ctx.proxies.len()];
        let body = proxy.get_json(&format!("/v1/strokes/{stroke}/placements"), &ctx.session).await;
        let history: PlacementHistory = serde_json::from_value(body).unwrap();
        let stored: Vec<(Exact, &str, Uuid)> = history
            .placements
            .iter()
            .map(|c| (bits(&c.placement), c.cause.as_str(), c.by))
            .collect();
        let wanted: Vec<(Exact, &str, Uuid)> =
            a.placements.iter().map(|(p, cause)| (*p, *cause, a.drawer)).collect();
        assert_eq!(stored, wanted, "the placement history of {stroke}");
    }

    // No request answered with a 5xx, on the socket or over HTTP.
    let metrics = ctx.proxies[0].metrics().await;
    let errors = internal_errors(&metrics) - errors_before.0;
    assert_eq!(errors, 0.0, "the proxy answered {errors} requests with a 5xx");
    let errors = socket_internal_errors(&metrics) - errors_before.1;
    assert_eq!(errors, 0.0, "the proxy sent {errors} internal errors on sockets");
}
