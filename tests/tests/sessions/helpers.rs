//! A participant that draws and watches at once, and the strict record of what it sees of the
//! others: any repeat, gap or out-of-order event fails the test where it arrives.

use std::collections::{BTreeMap, HashMap};

use penmesh::Sample;
use penmesh::protocol::{
    ClientMessage, ErrorCode, Hello, PROTOCOL_VERSION, ServerMessage, StrokeId, Welcome,
};
use penmesh_e2e::{
    POSTGRES_ENV, TestDatabase, TestProxy, TestSession, WsClient, assemble_retained,
    batch_simplified, spawn_proxy_on, spawn_replica, stroke_samples,
};
use uuid::Uuid;

/// One peer stroke as a participant received it.
#[derive(Debug, Clone, PartialEq)]
pub struct PeerStroke {
    pub participant: Uuid,
    pub retained: Vec<Sample>,
    pub done: bool,
    pub meshes: u32,
    /// Taken back (`StrokeRemoved`), until brought back (`StrokeRestored`).
    pub removed: bool,
    /// Its latest `PeerPlacement` (protocol version 5); `None`: never told (the identity).
    pub placement: Option<penmesh::Placement>,
    /// Its latest `PeerSolid` (protocol version 6); `None`: never told (the rod).
    pub solid: Option<penmesh::Solid>,
}

/// Everything a participant received of the others, checked as it arrives.
#[derive(Debug, Default, Clone)]
pub struct View {
    pub strokes: BTreeMap<StrokeId, PeerStroke>,
    pub present: HashMap<Uuid, String>,
    pub n_synced: usize,
    pub n_lagged: usize,
    /// `PeerStrokes` messages received (a history's strokes, several to a message).
    pub n_messages_of_strokes: usize,
}

impl View {
    /// Records a session event; panics on a repeat, a gap or an event out of order.
    pub fn apply(&mut self, msg: &ServerMessage) {
        match msg {
            ServerMessage::PeerJoined(j) => {
                assert!(
                    self.present.insert(j.participant, j.name.clone()).is_none(),
                    "joined twice"
                );
            }
            // A history's strokes, several to a message: each as its own events would be.
            ServerMessage::PeerStrokes(strokes) => {
                self.n_messages_of_strokes += 1;
                for msg in strokes.messages() {
                    self.apply(&msg);
                }
            }
            ServerMessage::PeerRenamed(r) => {
                let name = self.present.get_mut(&r.participant).expect("renamed while absent");
                *name = r.name.clone();
            }
            ServerMessage::PeerLeft(l) => {
                assert!(self.present.remove(&l.participant).is_some(), "left without joining");
            }
            ServerMessage::PeerStrokeBegin(b) => {
                let fresh = PeerStroke {
                    participant: b.participant,
                    retained: Vec::new(),
                    done: false,
                    meshes: 0,
                    removed: false,
                    placement: None,
                    solid: None,
                };
                assert!(self.strokes.insert(b.stroke, fresh).is_none(), "stroke begun twice");
            }
            ServerMessage::PeerRetained(r) => {
                let s = self.strokes.get_mut(&r.stroke).expect("retained before begin");
                assert!(!s.done, "retained after done");
                assert_eq!(r.participant, s.participant);
                assert_eq!(
                    r.first,
                    s.retained.len() as u64,
                    "retained samples from {} after {}: a gap or a repeat",
                    r.first,
                    s.retained.len()
                );
                s.retained.extend_from_slice(&r.points.0);
            }
            ServerMessage::PeerStrokeDone(d) => {
                let s = self.strokes.get_mut(&d.stroke).expect("done before begin");
                assert!(!s.done, "done twice");
                assert_eq!(d.n_retained, s.retained.len() as u64, "done with samples missing");
                assert_eq!(d.url, format!("/v1/strokes/{}/simplified", d.stroke));
                s.done = true;
            }
            ServerMessage::PeerMesh(m) => {
                let s = self.strokes.get_mut(&m.stroke).expect("mesh before begin");
                assert!(s.done, "mesh before done");
                assert_eq!(m.url, format!("/v1/strokes/{}/mesh", m.stroke));
                s.meshes += 1;
            }
            // Of a peer stroke this view holds; the participant's own strokes are not in it.
            ServerMessage::StrokeRemoved(r) => {
                if let Some(s) = self.strokes.get_mut(&r.stroke) {
                    assert!(s.done, "removed before done");
                    assert!(!s.removed, "removed twice");
                    assert_eq!(r.participant, s.participant);
                    s.removed = true;
                }
            }
            ServerMessage::StrokeRestored(r) => {
                let s = self.strokes.get_mut(&r.stroke);
                if let Some(s) = s {
                    assert!(s.removed, "restored while not removed");
                    s.removed = false;
                }
            }
            // Of a peer stroke this view holds (the answer about an own stroke is not).
            ServerMessage::PeerPlacement(p) => {
                if let Some(s) = self.strokes.get_mut(&p.stroke) {
                    assert_eq!(p.participant, s.participant);
                    s.placement = Some(p.placement);
                }
            }
            // Of a peer stroke this view holds (version 6).
            ServerMessage::PeerSolid(p) => {
                if let Some(s) = self.strokes.get_mut(&p.stroke) {
                    assert_eq!(p.participant, s.participant);
                    s.solid = Some(p.solid);
                }
            }
            ServerMessage::Synced(synced) => {
                self.n_synced += 1;
                assert_eq!(synced.n_strokes, self.strokes.len() as u64);
            }
            ServerMessage::Error(e) if e.code == ErrorCode::Lagged => self.n_lagged += 1,
            _ => {}
        }
    }

    pub fn n_done(&self) -> usize {
        self.strokes.values().filter(|s| s.done).count()
    }

    pub fn n_meshes(&self) -> u32 {
        self.strokes.values().map(|s| s.meshes).sum()
    }
}

/// A client that draws its own strokes and records the others'.
#[derive(Debug)]
pub struct Participant {
    pub ws: WsClient,
    /// Its participant key (`Hello.key`): a reconnect with it is the same participant.
    pub key: String,
    pub welcome: Welcome,
    pub view: View,
    /// The retained samples of this participant's own strokes, as streamed back.
    pub own: BTreeMap<StrokeId, Vec<Sample>>,
}

impl Participant {
    /// Connects as a new participant (a key of its own), says hello with `name`, and reads
    /// the history up to `Synced`.
    pub async fn join(proxy: &TestProxy, session: &TestSession, name: &str) -> Participant {
        Participant::join_resuming(proxy, session, name, &penmesh_e2e::new_key(), vec![]).await
    }

    /// Connects as the participant of `key` and resumes its strokes `resume`.
    pub async fn join_resuming(
        proxy: &TestProxy,
        session: &TestSession,
        name: &str,
        key: &str,
        resume: Vec<StrokeId>,
    ) -> Participant {
        let mut ws = proxy.connect(session).await;
        ws.send(&ClientMessage::Hello(Hello {
            protocol: PROTOCOL_VERSION,
            client: "penmesh-e2e".into(),
            name: Some(name.into()),
            resume,
            key: Some(key.into()),
        }))
        .await;
        let welcome = match ws.recv_any().await {
            ServerMessage::Welcome(welcome) => welcome,
            other => panic!("expected welcome, got {other:?}"),
        };
        let key = key.to_string();
        let mut me = Participant { ws, key, welcome, view: View::default(), own: BTreeMap::new() };
        me.wait_for(|v| v.n_synced >= 1).await;
        me
    }

    /// The next message; session events are recorded in the view.
    pub async fn recv(&mut self) -> ServerMessage {
        let msg = self.ws.recv_any().await;
        // A mesh of its own stroke (stored over HTTP) is announced to it too; the view holds
        // only the others' strokes.
        let own_mesh =
            matches!(&msg, ServerMessage::PeerMesh(m) if self.own.contains_key(&m.stroke));
        if !own_mesh {
            self.view.apply(&msg);
        }
        if let ServerMessage::Retained(r) = &msg {
            let own = self.own.entry(r.stroke).or_default();
            let mut pieces = vec![(0, std::mem::take(own))];
            pieces.push((r.first, r.points.0.clone()));
            *own = assemble_retained(&pieces);
        }
        msg
    }

    /// Reads until `done` holds for the view.
    pub async fn wait_for(&mut self, done: impl Fn(&View) -> bool) {
        while !done(&self.view) {
            self.recv().await;
        }
    }

    /// Reads until `pred` matches a message, which is returned; errors other than `lagged`
    /// fail the test.
    pub async fn recv_until(&mut self, pred: impl Fn(&ServerMessage) -> bool) -> ServerMessage {
        loop {
            let msg = self.recv().await;
            if let ServerMessage::Error(e) = &msg {
                assert_eq!(e.code, ErrorCode::Lagged, "unexpected error: {e:?}");
            }
            if pred(&msg) {
                return msg;
            }
        }
    }

    pub async fn begin(&mut self, stroke: StrokeId) {
        self.ws.begin(stroke).await;
        self.wait_ack(stroke, 0).await;
    }

    pub async fn wait_ack(&mut self, stroke: StrokeId, upto: u64) {
        self.recv_until(
            |m| matches!(m, ServerMessage::Ack(a) if a.stroke == stroke && a.upto_seq >= upto),
        )
        .await;
    }

    /// Sends `samples[from..to]` in batches of `batch`.
    pub async fn send_points(
        &mut self,
        stroke: StrokeId,
        samples: &[Sample],
        from: usize,
        to: usize,
        batch: usize,
    ) {
        let mut seq = from;
        while seq < to {
            let end = (seq + batch).min(to);
            self.ws.points(stroke, seq as u64, &samples[seq..end]).await;
            seq = end;
        }
    }

    pub async fn finish(&mut self, stroke: StrokeId, n_points: usize) {
        self.ws.end(stroke, n_points as u64).await;
        self.recv_until(|m| matches!(m, ServerMessage::StrokeDone(d) if d.stroke == stroke)).await;
    }

    /// Draws a whole stroke and waits for its `StrokeDone`.
    pub async fn draw(&mut self, stroke: StrokeId, samples: &[Sample], batch: usize) {
        self.begin(stroke).await;
        self.send_points(stroke, samples, 0, samples.len(), batch).await;
        self.wait_ack(stroke, samples.len() as u64).await;
        self.finish(stroke, samples.len()).await;
        assert_eq!(self.own[&stroke], batch_simplified(samples), "own retained samples");
    }

    /// [`Participant::draw`] at a pen's pace: each batch waits for its ack, so the proxy reads
    /// and stores it alone (batches sent back to back may be read together, stored as one
    /// request and told to the peers as one event).
    pub async fn draw_paced(&mut self, stroke: StrokeId, samples: &[Sample], batch: usize) {
        self.begin(stroke).await;
        for start in (0..samples.len()).step_by(batch) {
            let end = (start + batch).min(samples.len());
            self.send_points(stroke, samples, start, end, batch).await;
            self.wait_ack(stroke, end as u64).await;
        }
        self.finish(stroke, samples.len()).await;
        assert_eq!(self.own[&stroke], batch_simplified(samples), "own retained samples");
    }
}

/// The samples of stroke number `k`: the test stroke moved so that every stroke differs.
pub fn samples_for(k: usize, n: usize) -> Vec<Sample> {
    stroke_samples(n)
        .into_iter()
        .map(|s| {
            let moved = Sample::new(s.x + 1000.0 * k as f64, s.y + 7.0 * k as f64, s.t, s.p);
            penmesh::protocol::quantize_sample(&moved)
        })
        .collect()
}

/// Stores a mesh for a done stroke over HTTP.
pub async fn put_mesh(
    proxy: &TestProxy,
    drawer: &Participant,
    session: &TestSession,
    stroke: StrokeId,
) {
    let drawer = TestSession { key: drawer.key.clone(), ..session.clone() };
    let response =
        proxy.put_mesh(&drawer, stroke, penmesh_e2e::minimal_glb(3, 3)).send().await.unwrap();
    assert_eq!(response.status(), 200, "PUT mesh");
}

/// Two replicas on one fresh PostgreSQL database. PostgreSQL must work: without
/// `PENMESH_TEST_POSTGRES_URL`, or with a server that fails, the test fails.
pub async fn two_replicas() -> (TestProxy, TestProxy) {
    let db = TestDatabase::fresh().await;
    assert!(db.is_postgres(), "two replicas need PostgreSQL: set {POSTGRES_ENV}");
    let a = spawn_replica(db.clone(), |_| {}).await;
    let b = spawn_replica(db, |_| {}).await;
    (a, b)
}

/// The proxies a test spreads its participants over: two replicas with PostgreSQL, else one.
pub async fn one_or_two_replicas(tweak: impl Fn(&mut penmesh_proxy::Config)) -> Vec<TestProxy> {
    let db = TestDatabase::fresh().await;
    if db.is_postgres() {
        vec![spawn_replica(db.clone(), &tweak).await, spawn_replica(db, &tweak).await]
    } else {
        vec![spawn_proxy_on(db, &tweak).await]
    }
}

/// What every participant must end with: each stroke's simplified samples, done, and meshes.
pub fn expected_view(
    strokes: &[(StrokeId, Vec<Sample>)],
    meshes: &[StrokeId],
) -> BTreeMap<StrokeId, (Vec<Sample>, bool, u32)> {
    strokes
        .iter()
        .map(|(id, samples)| {
            (
                *id,
                (
                    batch_simplified(samples),
                    true,
                    meshes.iter().filter(|m| *m == id).count() as u32,
                ),
            )
        })
        .collect()
}

/// Checks that `p` has every stroke of `expected` exactly once, complete and in its final
/// state: its own strokes as streamed back to it, the others' as received.
pub fn check_complete(p: &Participant, expected: &BTreeMap<StrokeId, (Vec<Sample>, bool, u32)>) {
    let mut n_peer = 0;
    for (id, (samples, done, meshes)) in expected {
        match p.own.get(id) {
            Some(own) => assert_eq!(own, samples, "own stroke {id}"),
            None => {
                n_peer += 1;
                let seen = p.view.strokes.get(id).unwrap_or_else(|| panic!("stroke {id} missing"));
                assert_eq!(&seen.retained, samples, "stroke {id}");
                assert_eq!((seen.done, seen.meshes), (*done, *meshes), "stroke {id}");
            }
        }
    }
    assert_eq!(p.view.strokes.len(), n_peer, "strokes seen that were never drawn");
}
