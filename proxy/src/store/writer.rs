//! Group commit: one task owns the write connection and commits the pending writes of every
//! connection in one transaction, then tells each requester.
//!
//! Connections send [`WriteOp`]s over a bounded queue (a full queue makes them wait: back
//! pressure, never unbounded memory). The writer takes the first request, waits until at least
//! `commit_interval` has passed since its previous commit began, drains whatever else is
//! pending (up to `commit_max_requests`), and commits it all in ONE transaction. Only then does
//! each requester hear `Ok`, so an `Ack` always means "committed". If the group transaction
//! fails, each request is retried in a transaction of its own, so one bad request cannot fail
//! the others.
//!
//! A group's appends go to the database as one record of the append log (`super::log`); a
//! stroke's samples move into `stroke_chunks` when it ends, is interrupted, or has been in the
//! log for `log::MOVE_AFTER`, in the transaction of that commit.
//!
//! An append is stored only where its stroke's stored samples end (`WriterLoop::strokes`): one
//! that would leave a hole (an earlier append of its stroke failed) is refused, samples already
//! stored (a commit that succeeded but reported failure, retried) are not written again. So a
//! stroke's stored samples stay contiguous from 0, with no overlap, whatever fails.
//!
//! Every transaction has a deadline (`--db-timeout-ms`, [`Store::deadline`]): a database that
//! stops answering (a network partition leaves the socket silent, and nothing else would ever
//! end the wait) fails the requests of the transaction in flight. After any failed transaction
//! the writer drops its connection and opens a new one for the next. Whether the failed
//! `COMMIT` took effect is unknown: the next transaction reads the ends again, and the clients
//! resume from what is stored.
//!
//! A request may carry session events ([`SessionEvent`]) that describe it. They are published
//! only once the request is committed, in commit order: with PostgreSQL as notifications of
//! the same transaction (so every replica's listener gets them, or none does), with SQLite
//! straight to the local [`Fanout`] after `COMMIT`, before the next transaction begins.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use penmesh::protocol::StrokeStatus;
use penmesh::{AcutsParams, Brush, Kept, Sample};
use sqlx::{AnyConnection, Connection, Row};
use tokio::sync::{mpsc, oneshot};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

use super::log::{self, MOVE_AFTER, Piece};
use super::{Backend, MeshRow, Store, encode_indices, encode_samples, notify, now_ms};
use crate::fanout::{Fanout, SessionEvent};

/// One change to the database.
#[derive(Debug, Clone)]
pub enum WriteOp {
    /// Creates a stroke (nothing if it exists already).
    BeginStroke {
        stroke: Uuid,
        session: Uuid,
        participant: Uuid,
        brush: Brush,
        params: AcutsParams,
        device: Option<String>,
    },
    /// Appends the samples `seq..seq + samples.len()` of a stroke.
    Append { stroke: Uuid, seq: u64, samples: Vec<Sample> },
    /// Stores the simplified stroke and marks it `done`.
    Finish { stroke: Uuid, kept: Vec<Kept> },
    /// Sets a stroke's status (`open` when resumed, `interrupted` when its connection ends).
    SetStatus { stroke: Uuid, status: StrokeStatus },
    /// A participant said hello in a session on `connection` (its presence row).
    /// `replica` is the key of the lock the replica holds while it lives (PostgreSQL).
    Join { connection: Uuid, participant: Uuid, session: Uuid, name: String, replica: Option<i64> },
    /// A participant's connection ended.
    Leave { connection: Uuid },
    /// Stores (or replaces) a done stroke's mesh, unless the meshes of `session` would then
    /// hold more than `quota` bytes (refused: [`WriteError::Quota`]). A request of its own: it
    /// is written where it is planned, as only the write tells whether it fits.
    PutMesh { stroke: Uuid, session: Uuid, mesh: MeshRow, quota: u64 },
    /// Keeps what ACUTS retains of a stroke's first `upto` samples before its end (`kept`), so
    /// that the next history of its session need not replay them (`Store::session_history`).
    /// Never replaces the simplified stroke of a stroke that is done.
    KeepRetained { stroke: Uuid, upto: u64, kept: Vec<Kept> },
}

impl WriteOp {
    /// Bytes of samples the op holds while it waits for the writer.
    fn sample_bytes(&self) -> usize {
        match self {
            WriteOp::Append { samples, .. } => std::mem::size_of_val(samples.as_slice()),
            WriteOp::Finish { kept, .. } | WriteOp::KeepRetained { kept, .. } => {
                std::mem::size_of_val(kept.as_slice())
            }
            _ => 0,
        }
    }

    /// Bytes of mesh the op writes.
    fn mesh_bytes(&self) -> usize {
        match self {
            WriteOp::PutMesh { mesh, .. } => mesh.glb.len(),
            _ => 0,
        }
    }

    fn n_samples(&self) -> usize {
        match self {
            WriteOp::Append { samples, .. } => samples.len(),
            _ => 0,
        }
    }
}

/// The writer failed to commit a request.
#[derive(Debug, Clone, thiserror::Error)]
pub enum WriteError {
    #[error("the writer has stopped")]
    Closed,
    /// The database failed; its own words, for the log.
    #[error("database write failed: {0}")]
    Database(String),
    /// The database could not write for want of space or a failing disk (its own words, for
    /// the log): the one database failure a client is told the cause of.
    #[error("the database cannot write to its disk: {0}")]
    Storage(String),
    /// The writer refused the request: storing it would break a stroke's stored samples (a
    /// hole, samples after its end, a stroke that does not exist). The message is the
    /// writer's own, fit for the client.
    #[error("{0}")]
    Refused(String),
    /// The write would pass a storage quota (the message names it); nothing was written.
    #[error("{0}")]
    Quota(String),
}

/// The answer to a submitted request: ready once it is committed (or failed). A named type, not
/// a boxed future, so that a connection keeps its requests in a plain queue (one allocation
/// less per batch, `ws::connection`).
#[derive(Debug)]
pub struct Committed {
    /// `None`: the request never reached the writer.
    answer: Option<oneshot::Receiver<Result<(), WriteError>>>,
}

impl Future for Committed {
    type Output = Result<(), WriteError>;

    fn poll(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Self::Output> {
        match &mut self.answer {
            None => std::task::Poll::Ready(Err(WriteError::Closed)),
            Some(rx) => {
                std::pin::Pin::new(rx).poll(cx).map(|r| r.unwrap_or(Err(WriteError::Closed)))
            }
        }
    }
}

/// What an injected fault does to the transaction it hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The transaction fails before `COMMIT`: nothing of it is stored.
    Fail,
    /// `COMMIT` succeeds, then the writer is told it failed (the connection dropped while the
    /// reply was on its way).
    FailAfterCommit,
}

/// Failures injected into the writer's transactions, for the tests of its failure paths. The
/// proxy never sets any outside tests ([`crate::Application::build_with_faults`]).
#[derive(Debug, Default)]
pub struct CommitFaults {
    state: Mutex<FaultState>,
}

#[derive(Debug, Default)]
struct FaultState {
    /// Transactions begun so far (group commits and retries alike).
    transactions: u64,
    rules: Vec<FaultRule>,
}

#[derive(Debug)]
struct FaultRule {
    target: FaultTarget,
    fault: Fault,
    /// How many more transactions it hits.
    remaining: u32,
}

#[derive(Debug)]
enum FaultTarget {
    /// The transaction the writer begins `k`th (1-based).
    Transaction(u64),
    /// Any transaction holding the append of `stroke` submitted at `seq`.
    Append { stroke: Uuid, seq: u64 },
    /// Any transaction holding the begin of `stroke`.
    Begin { stroke: Uuid },
}

impl CommitFaults {
    pub fn new() -> Arc<CommitFaults> {
        Arc::new(CommitFaults::default())
    }

    /// The `k`th transaction from now (1: the next one; retries count) gets `fault`.
    pub fn fail_transaction(&self, k: u64, fault: Fault) {
        let mut state = self.state.lock().expect("faults lock");
        let target = FaultTarget::Transaction(state.transactions + k);
        state.rules.push(FaultRule { target, fault, remaining: 1 });
    }

    /// The next `times` transactions that hold the append of `stroke` at `seq` get `fault`.
    pub fn fail_append(&self, stroke: Uuid, seq: u64, fault: Fault, times: u32) {
        let rule =
            FaultRule { target: FaultTarget::Append { stroke, seq }, fault, remaining: times };
        self.state.lock().expect("faults lock").rules.push(rule);
    }

    /// The next `times` transactions that hold the begin of `stroke` get `fault`.
    pub fn fail_begin(&self, stroke: Uuid, fault: Fault, times: u32) {
        let rule = FaultRule { target: FaultTarget::Begin { stroke }, fault, remaining: times };
        self.state.lock().expect("faults lock").rules.push(rule);
    }

    /// Removes every fault not yet spent.
    pub fn clear(&self) {
        self.state.lock().expect("faults lock").rules.clear();
    }

    /// Counts a transaction of `requests` and says which fault, if any, hits it.
    fn hit(&self, requests: &[&WriteRequest]) -> Option<Fault> {
        let mut state = self.state.lock().expect("faults lock");
        state.transactions += 1;
        let k = state.transactions;
        let holds = |stroke: &Uuid, seq: &u64| {
            requests.iter().flat_map(|r| &r.ops).any(|op| {
                matches!(op, WriteOp::Append { stroke: s, seq: q, .. } if s == stroke && q == seq)
            })
        };
        let begins = |stroke: &Uuid| {
            requests
                .iter()
                .flat_map(|r| &r.ops)
                .any(|op| matches!(op, WriteOp::BeginStroke { stroke: s, .. } if s == stroke))
        };
        let rule = state.rules.iter_mut().find(|r| {
            r.remaining > 0
                && match &r.target {
                    FaultTarget::Transaction(n) => *n == k,
                    FaultTarget::Append { stroke, seq } => holds(stroke, seq),
                    FaultTarget::Begin { stroke } => begins(stroke),
                }
        })?;
        rule.remaining -= 1;
        Some(rule.fault)
    }
}

struct WriteRequest {
    ops: Vec<WriteOp>,
    events: Vec<SessionEvent>,
    done: oneshot::Sender<Result<(), WriteError>>,
    /// The request's share of the queue's bytes, given back when the request is dropped.
    _bytes: Option<tokio::sync::OwnedSemaphorePermit>,
}

/// The sending side, cloned into every connection.
#[derive(Debug, Clone)]
pub struct Writer {
    tx: mpsc::Sender<WriteRequest>,
    /// Bytes of samples queued or being committed, at most the semaphore's size (none: no
    /// limit but the count).
    bytes: Option<(Arc<tokio::sync::Semaphore>, u32)>,
}

impl Writer {
    /// Bounds the bytes of samples queued into the writer (and not yet committed) by `limit`,
    /// next to the count of requests: a sender waits until they fit. A request larger than
    /// the whole limit waits for the queue to be empty of samples.
    pub fn limit_bytes(self, limit: usize) -> Writer {
        let limit = limit.clamp(1, u32::MAX as usize) as u32;
        Writer {
            bytes: Some((Arc::new(tokio::sync::Semaphore::new(limit as usize)), limit)),
            ..self
        }
    }

    /// Queues `ops` (waiting while the queue is full) and returns a future that resolves once
    /// they are committed.
    pub async fn submit(&self, ops: Vec<WriteOp>) -> Committed {
        self.submit_with(ops, Vec::new()).await
    }

    /// Like [`Writer::submit`], and publishes `events` once `ops` are committed.
    pub async fn submit_with(&self, ops: Vec<WriteOp>, events: Vec<SessionEvent>) -> Committed {
        let (done, rx) = oneshot::channel();
        let bytes = match &self.bytes {
            Some((semaphore, limit)) => {
                let n: usize = ops.iter().map(WriteOp::sample_bytes).sum();
                let n = n.min(*limit as usize) as u32;
                match n {
                    0 => None,
                    n => semaphore.clone().acquire_many_owned(n).await.ok(),
                }
            }
            None => None,
        };
        let request = WriteRequest { ops, events, done, _bytes: bytes };
        let queued = self.tx.send(request).await.is_ok();
        Committed { answer: queued.then_some(rx) }
    }

    /// Queues `ops` and waits for the commit.
    pub async fn write(&self, ops: Vec<WriteOp>) -> Result<(), WriteError> {
        self.submit(ops).await.await
    }

    /// Queues `ops` with their `events` and waits for the commit.
    pub async fn write_with(
        &self,
        ops: Vec<WriteOp>,
        events: Vec<SessionEvent>,
    ) -> Result<(), WriteError> {
        self.submit_with(ops, events).await.await
    }
}

/// The thread that owns the write connection.
///
/// The writer runs on a thread of its own, with its own single-threaded runtime: a group commit
/// is a chain of round trips to the database (with SQLite, to sqlx's worker thread), and on the
/// shared runtime each of them queued behind every ready connection task. Under 500 pens that
/// made a commit last 13 ms, while neither the writer nor SQLite was busy.
#[derive(Debug)]
pub struct WriterTask {
    thread: std::thread::JoinHandle<()>,
    stop: CancellationToken,
}

impl WriterTask {
    /// Opens the write connection and starts the writer. The store's deadline bounds each
    /// transaction (and each reconnection). `writer_id` is the id its log records carry: with
    /// PostgreSQL the replica's lock key, so that other replicas can tell when the writer died
    /// (`cluster::reap_log`); random when `None`.
    pub async fn start(
        store: &Store,
        commit_interval: Duration,
        max_requests: usize,
        queue: usize,
        fanout: Fanout,
        faults: Option<Arc<CommitFaults>>,
        writer_id: Option<i64>,
    ) -> anyhow::Result<(Writer, WriterTask)> {
        let (tx, rx) = mpsc::channel(queue.max(1));
        let deadline = store.deadline();
        let stop = CancellationToken::new();
        let (store, loop_stop) = (store.clone(), stop.clone());
        let (opened_tx, opened) = oneshot::channel::<anyhow::Result<()>>();
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let thread =
            std::thread::Builder::new().name("penmesh-writer".into()).spawn(move || {
                runtime.block_on(async move {
                    let opened = tokio::time::timeout(deadline, store.open_write_connection())
                        .await
                        .unwrap_or_else(|_| Err(timed_out(deadline)));
                    let conn = match opened {
                        Ok(conn) => conn,
                        Err(err) => {
                            let _ = opened_tx.send(Err(err));
                            return;
                        }
                    };
                    let _ = opened_tx.send(Ok(()));
                    let state = WriterLoop {
                        begin: store.begin_statement(),
                        store,
                        conn: Some(conn),
                        rx,
                        interval: commit_interval,
                        deadline,
                        max_requests: max_requests.max(1),
                        stop: loop_stop,
                        fanout,
                        strokes: HashMap::new(),
                        writer_id: writer_id.unwrap_or_else(|| (rand::random::<u64>() >> 1) as i64),
                        trimmed_below: 0,
                        last_record: 0,
                        recover: false,
                        idle_checked: Instant::now(),
                        idle_moved: false,
                        faults,
                    };
                    state.run().await
                })
            })?;
        match opened.await {
            Ok(Ok(())) => Ok((Writer { tx, bytes: None }, WriterTask { thread, stop })),
            Ok(Err(err)) => Err(err.context("opening the writer's database connection")),
            Err(_) => anyhow::bail!("the writer thread ended while opening its connection"),
        }
    }

    /// Commits whatever is queued, then stops. Requests sent later get [`WriteError::Closed`].
    pub async fn stop(self) {
        self.stop.cancel();
        let thread = self.thread;
        if !matches!(tokio::task::spawn_blocking(move || thread.join()).await, Ok(Ok(()))) {
            tracing::error!("the writer thread panicked");
        }
    }
}

struct WriterLoop {
    store: Store,
    /// `None` after a failure that left it unusable: the next transaction opens a new one.
    conn: Option<AnyConnection>,
    begin: &'static str,
    rx: mpsc::Receiver<WriteRequest>,
    interval: Duration,
    /// The longest a transaction (or a reconnection) may take.
    deadline: Duration,
    max_requests: usize,
    stop: CancellationToken,
    fanout: Fanout,
    /// The strokes this writer appends to, as committed: where their stored samples end (an
    /// append must start there, or repeat what is stored: that is what keeps every stroke
    /// contiguous from 0 whatever failed before) and which of them are only in the log. Only
    /// strokes open on this replica are here (`Finish` and `SetStatus` move and forget one);
    /// after a failed transaction nothing is known: the next transaction rebuilds this from
    /// this writer's records (`recover`), and any other stroke is read again from the database
    /// inside the transaction that needs it.
    strokes: HashMap<Uuid, Known>,
    /// This writer's records in `stroke_log` carry this id (a new one each start).
    writer_id: i64,
    /// This writer's records below this id are deleted.
    trimmed_below: i64,
    /// The id of this writer's latest record.
    last_record: i64,
    /// `strokes` must be rebuilt from the database (a transaction failed).
    recover: bool,
    /// When the strokes were last checked for samples in the log longer than `MOVE_AFTER`.
    idle_checked: Instant,
    /// The last transaction moved strokes because they sat in the log long enough: a failure
    /// may be theirs, not its requests'.
    idle_moved: bool,
    faults: Option<Arc<CommitFaults>>,
}

/// What the writer knows of a stroke, as committed.
#[derive(Debug, Clone, Default)]
struct Known {
    /// `stroke_chunks` holds the samples `0..chunk_end`.
    chunk_end: u64,
    /// The samples after `chunk_end`, stored only in the log.
    pending: Vec<Sample>,
    /// The oldest of this writer's records holding some of `pending`, if any.
    first_record: Option<i64>,
    /// Since when `pending` is not empty.
    since: Option<Instant>,
}

impl Known {
    fn end(&self) -> u64 {
        self.chunk_end + self.pending.len() as u64
    }
}

/// Records are deleted from the front of the log when this many can go at once (a delete
/// dirties the pages it frees; fewer, larger deletes dirty each page once).
const TRIM_RECORDS: i64 = 64;
/// How often the writer looks for strokes to move because they sat in the log long enough.
const IDLE_CHECK: Duration = Duration::from_millis(100);

/// An op as it will be written: an append trimmed to what is not stored yet.
enum Planned<'a> {
    Append { stroke: Uuid, seq: u64, samples: &'a [Sample] },
    Other(&'a WriteOp),
}

/// The stroke a `Finish` or `SetStatus` closes: its samples leave the log, it leaves the writer.
fn closes(op: &WriteOp) -> Option<Uuid> {
    match op {
        WriteOp::Finish { stroke, .. } | WriteOp::SetStatus { stroke, .. } => Some(*stroke),
        _ => None,
    }
}

/// Most bytes of meshes one transaction writes (more go in the next): what a mesh upload may
/// add to the commit of everyone's samples that shares its transaction.
const MESH_BYTES_PER_COMMIT: usize = 16 << 20;

/// How many of `batch`'s requests go in one transaction: up to (not including) the first that
/// appends to a stroke an earlier request closed, so that a transaction moves a stroke out of
/// the log after all of its appends, or that would take the meshes past
/// [`MESH_BYTES_PER_COMMIT`].
fn first_group(batch: &[WriteRequest]) -> usize {
    let mut closed = std::collections::HashSet::new();
    let mut mesh_bytes = 0;
    for (i, req) in batch.iter().enumerate() {
        let reopens = req
            .ops
            .iter()
            .any(|op| matches!(op, WriteOp::Append { stroke, .. } if closed.contains(stroke)));
        mesh_bytes += req.ops.iter().map(WriteOp::mesh_bytes).sum::<usize>();
        if (reopens || mesh_bytes > MESH_BYTES_PER_COMMIT) && i > 0 {
            return i;
        }
        closed.extend(req.ops.iter().filter_map(closes));
    }
    batch.len()
}

impl WriterLoop {
    async fn run(mut self) {
        let mut last_commit = Instant::now() - self.interval;
        let mut batch = Vec::with_capacity(self.max_requests);
        loop {
            let first = tokio::select! {
                req = self.rx.recv() => req,
                _ = self.stop.cancelled() => None,
            };
            let Some(first) = first else { break };
            batch.push(first);
            let wait_until = last_commit + self.interval;
            if Instant::now() < wait_until && !self.stop.is_cancelled() {
                tokio::time::sleep_until(wait_until.into()).await;
            }
            while batch.len() < self.max_requests {
                match self.rx.try_recv() {
                    Ok(req) => batch.push(req),
                    Err(_) => break,
                }
            }
            last_commit = Instant::now();
            self.commit_batch(&mut batch).await;
        }
        // Stopping: commit what is still queued, then refuse the rest.
        self.rx.close();
        while let Ok(req) = self.rx.try_recv() {
            batch.push(req);
            if batch.len() >= self.max_requests {
                self.commit_batch(&mut batch).await;
            }
        }
        self.commit_batch(&mut batch).await;
        // And leave the log empty: every stroke's samples in `stroke_chunks`.
        if let Err(err) = self.commit(&[], true).await {
            tracing::warn!(error = %err, "moving the strokes out of the log at stop");
        }
    }

    async fn commit_batch(&mut self, batch: &mut Vec<WriteRequest>) {
        while !batch.is_empty() {
            let k = first_group(batch);
            let mut group: Vec<WriteRequest> = batch.drain(..k).collect();
            self.commit_group(&mut group).await;
        }
    }

    async fn commit_group(&mut self, batch: &mut Vec<WriteRequest>) {
        let started = Instant::now();
        let n_samples: usize = batch.iter().flat_map(|r| &r.ops).map(WriteOp::n_samples).sum();
        let all: Vec<&WriteRequest> = batch.iter().collect();
        let result = self.commit(&all, false).await;
        metrics::histogram!("penmesh_commit_seconds").record(started.elapsed().as_secs_f64());
        metrics::histogram!("penmesh_commit_batch_requests").record(batch.len() as f64);
        metrics::histogram!("penmesh_commit_batch_samples").record(n_samples as f64);
        match result {
            Ok(refused) => {
                for (req, refusal) in batch.drain(..).zip(refused) {
                    self.answer(req, refusal.map_or(Ok(()), Err));
                }
            }
            // A request alone is answered with its failure, unless the transaction also moved
            // other strokes: then it is tried again alone (below), after the writer has looked
            // at what is stored again and set aside what cannot be moved (`recover`).
            Err(err) if batch.len() == 1 && !self.idle_moved => {
                tracing::error!(error = %err, "write failed");
                let req = batch.pop().expect("one request");
                let failure = self.failure(&err);
                self.answer(req, Err(failure));
            }
            Err(err) => {
                tracing::warn!(error = %err, n = batch.len(), "group commit failed; retrying each request alone");
                // In order, each in its own transaction. What the writer knew was forgotten with
                // the failure, so each append is checked against what is really stored: a group
                // that did commit after all makes its appends repeats (stored, nothing written),
                // and an append after one that failed would leave a hole, so it is refused.
                for req in batch.drain(..) {
                    let result = match self.commit(&[&req], false).await {
                        Ok(mut refused) => refused.pop().flatten().map_or(Ok(()), Err),
                        Err(err) => {
                            tracing::error!(error = %err, "write failed");
                            Err(self.failure(&err))
                        }
                    };
                    self.answer(req, result);
                }
            }
        }
    }

    /// A failed transaction as its requesters hear it: [`WriteError::Storage`] when the
    /// database could not write to its disk (SQLite: `SQLITE_FULL`, or `SQLITE_IOERR`, as a
    /// write refused for its size reads; PostgreSQL: class 53, insufficient resources, e.g.
    /// `disk_full`), else [`WriteError::Database`].
    fn failure(&self, err: &anyhow::Error) -> WriteError {
        let backend = self.store.backend();
        let storage = err
            .chain()
            .filter_map(|cause| cause.downcast_ref::<sqlx::Error>()?.as_database_error()?.code())
            .any(|code| match backend {
                Backend::Sqlite => code.parse::<i32>().is_ok_and(|c| matches!(c & 0xff, 10 | 13)),
                Backend::Postgres => code.starts_with("53"),
            });
        match storage {
            true => WriteError::Storage(err.to_string()),
            false => WriteError::Database(err.to_string()),
        }
    }

    /// Tells a requester how its request went, and publishes its events if it is committed.
    fn answer(&self, req: WriteRequest, result: Result<(), WriteError>) {
        match &result {
            Ok(()) => self.publish(req.events),
            Err(_) => {
                metrics::counter!("penmesh_commit_failures_total").increment(1);
            }
        }
        let _ = req.done.send(result);
    }

    /// With SQLite, hands committed events to the local fan-out (PostgreSQL notified them).
    fn publish(&self, events: Vec<SessionEvent>) {
        if self.store.backend() == Backend::Sqlite {
            for event in events {
                self.fanout.dispatch(event);
            }
        }
    }

    /// Commits `requests` in one transaction (and with `move_all`, moves every stroke out of
    /// the log). `Ok` holds, for each request, why it was refused (an append that would leave
    /// a hole), or `None`: committed.
    async fn commit(
        &mut self,
        requests: &[&WriteRequest],
        move_all: bool,
    ) -> anyhow::Result<Vec<Option<WriteError>>> {
        let deadline = self.deadline;
        let committed = tokio::time::timeout(deadline, self.try_commit(requests, move_all)).await;
        let result = committed.unwrap_or_else(|_| Err(timed_out(deadline)));
        if result.is_err() {
            // Whether anything of it is stored is unknown: rebuild what the writer knows.
            self.strokes.clear();
            self.recover = true;
            // Nor is the connection's state: a broken one (a database restart, a partition,
            // a deadline passed) may still answer a ping, and SQLite after SQLITE_FULL (a full
            // disk) keeps a transaction sqlx cannot roll back, so that every later BEGIN fails.
            // The next transaction opens a new connection.
            self.conn = None;
        }
        result
    }

    async fn try_commit(
        &mut self,
        requests: &[&WriteRequest],
        move_all: bool,
    ) -> anyhow::Result<Vec<Option<WriteError>>> {
        self.idle_moved = false;
        let fault = self.faults.as_ref().and_then(|f| f.hit(requests));
        let backend = self.store.backend();
        let conn = match &mut self.conn {
            Some(conn) => conn,
            None => {
                let conn = self.store.open_write_connection().await?;
                tracing::warn!("the write connection is open again");
                self.conn.insert(conn)
            }
        };
        let mut tx = conn.begin_with(self.begin).await?;
        if self.recover {
            // Valid whether or not this transaction commits: it is what is committed now.
            self.strokes = recover(&mut tx, self.writer_id).await?;
            self.recover = false;
        }
        let now = now_ms();
        // Strokes read from the database in this transaction, the ends as it leaves them, and
        // the strokes it closes (moved out of the log and forgotten once it commits).
        let mut loaded: HashMap<Uuid, Known> = HashMap::new();
        let mut ends: HashMap<Uuid, u64> = HashMap::new();
        let mut closed: Vec<Uuid> = Vec::new();
        let mut planned: Vec<Planned> = Vec::new();
        let mut refused = Vec::with_capacity(requests.len());
        // One request's plan, kept apart until it is known not to be refused (reused: a group
        // commit plans hundreds of requests).
        let mut req_ends: HashMap<Uuid, u64> = HashMap::new();
        let mut req_planned = Vec::new();
        // Strokes this transaction creates (the requests planned so far, and the one being
        // planned): they have no row yet, and exist once it commits.
        let mut creates: HashSet<Uuid> = HashSet::new();
        let mut req_creates: HashSet<Uuid> = HashSet::new();
        for req in requests {
            // A request is written whole or refused whole.
            req_ends.clear();
            req_planned.clear();
            req_creates.clear();
            let mut refusal = None;
            for op in &req.ops {
                if let WriteOp::PutMesh { stroke, session, mesh, quota } = op {
                    if let Err(why) = put_mesh(&mut tx, *stroke, *session, mesh, *quota).await? {
                        refusal = Some(why);
                        break;
                    }
                    continue;
                }
                let WriteOp::Append { stroke, seq, samples } = op else {
                    match op {
                        WriteOp::BeginStroke { stroke, .. } => {
                            req_creates.insert(*stroke);
                        }
                        // A stroke exists before anything of it is stored.
                        WriteOp::Finish { stroke, .. }
                            if !self.strokes.contains_key(stroke)
                                && !loaded.contains_key(stroke)
                                && !creates.contains(stroke)
                                && !req_creates.contains(stroke) =>
                        {
                            match load_stroke(&mut tx, *stroke, self.writer_id).await? {
                                Some(known) => {
                                    loaded.insert(*stroke, known);
                                }
                                None => {
                                    refusal = Some(no_stroke(*stroke));
                                    break;
                                }
                            }
                        }
                        _ => {}
                    }
                    closed.extend(closes(op));
                    req_planned.push(Planned::Other(op));
                    continue;
                };
                if closed.contains(stroke) {
                    refusal = Some(WriteError::Refused(format!(
                        "samples of stroke {stroke} after its end in the same request"
                    )));
                    break;
                }
                let known = req_ends
                    .get(stroke)
                    .or_else(|| ends.get(stroke))
                    .copied()
                    .or_else(|| self.strokes.get(stroke).map(Known::end))
                    .or_else(|| loaded.get(stroke).map(Known::end));
                let end = match known {
                    Some(end) => end,
                    None => match load_stroke(&mut tx, *stroke, self.writer_id).await? {
                        Some(known) => {
                            let end = known.end();
                            loaded.insert(*stroke, known);
                            end
                        }
                        None if creates.contains(stroke) || req_creates.contains(stroke) => {
                            loaded.insert(*stroke, Known::default());
                            0
                        }
                        // Its begin failed (or never came): nothing of it is stored or acked.
                        None => {
                            refusal = Some(no_stroke(*stroke));
                            break;
                        }
                    },
                };
                let upto = seq + samples.len() as u64;
                if *seq > end {
                    refusal = Some(WriteError::Refused(format!(
                        "samples {seq}..{upto} of stroke {stroke} would leave a hole: only \
                         {end} are stored"
                    )));
                    break;
                }
                if upto > end {
                    let samples = &samples[(end - seq) as usize..];
                    req_planned.push(Planned::Append { stroke: *stroke, seq: end, samples });
                }
                req_ends.insert(*stroke, end.max(upto));
            }
            if refusal.is_none() {
                planned.append(&mut req_planned);
                ends.extend(req_ends.drain());
                creates.extend(req_creates.drain());
            }
            refused.push(refusal);
        }
        // This transaction's appends, by stroke, for the moves.
        let mut appended: HashMap<Uuid, Vec<Sample>> = HashMap::new();
        let mut record: Vec<(Uuid, u64, &[Sample])> = Vec::new();
        for op in &planned {
            if let Planned::Append { stroke, seq, samples } = op {
                appended.entry(*stroke).or_default().extend_from_slice(samples);
                record.push((*stroke, *seq, samples));
            }
        }
        // The other ops in order; `Finish` and `SetStatus` move their stroke out of the log.
        let mut moved: Vec<Uuid> = Vec::new();
        // Strokes this transaction creates: nothing of them is stored before it.
        let mut begun: Vec<Uuid> = Vec::new();
        let mut moves: Vec<(Uuid, u64, Vec<Sample>)> = Vec::new();
        for op in &planned {
            let Planned::Other(op) = op else { continue };
            match op {
                WriteOp::Finish { stroke, kept } => {
                    // Known, or created by this transaction (checked when planned).
                    let base = match self.strokes.get(stroke).or_else(|| loaded.get(stroke)) {
                        Some(known) => known.clone(),
                        None => {
                            load_stroke(&mut tx, *stroke, self.writer_id).await?.unwrap_or_default()
                        }
                    };
                    let tail = appended.get(stroke).map(Vec::as_slice).unwrap_or_default();
                    finish(&mut tx, backend, *stroke, &base, tail, kept, now).await?;
                }
                WriteOp::SetStatus { stroke, .. } => {
                    if let Some(known) = self.strokes.get(stroke).or_else(|| loaded.get(stroke)) {
                        let mut samples = known.pending.clone();
                        samples.extend(appended.get(stroke).into_iter().flatten());
                        if !samples.is_empty() {
                            moves.push((*stroke, known.chunk_end, samples));
                        }
                    }
                    apply(&mut tx, op, now).await?;
                }
                WriteOp::BeginStroke { stroke, .. } => {
                    if apply(&mut tx, op, now).await? {
                        begun.push(*stroke);
                    }
                }
                _ => {
                    apply(&mut tx, op, now).await?;
                }
            }
        }
        // Strokes that sat in the log long enough move too (all of them when stopping).
        let check_idle = move_all || self.idle_checked.elapsed() >= IDLE_CHECK;
        if check_idle {
            let due = |k: &Known| move_all || k.since.is_some_and(|t| t.elapsed() >= MOVE_AFTER);
            for (stroke, known) in self.strokes.iter().chain(&loaded) {
                if closed.contains(stroke) || !due(known) {
                    continue;
                }
                let mut samples = known.pending.clone();
                samples.extend(appended.get(stroke).into_iter().flatten());
                moved.push(*stroke);
                moves.push((*stroke, known.chunk_end, samples));
            }
            self.idle_moved = !moved.is_empty();
        }
        let rows: Vec<(Uuid, u64, &[Sample])> =
            moves.iter().map(|(s, seq, samples)| (*s, *seq, samples.as_slice())).collect();
        insert_chunks(&mut tx, backend, &rows).await?;
        // The appends: one record.
        let record_id = if record.is_empty() {
            None
        } else {
            let id: i64 = sqlx::query_scalar(
                "INSERT INTO stroke_log (writer, data) VALUES ($1, $2) RETURNING id",
            )
            .bind(self.writer_id)
            .bind(log::encode_record(&record))
            .fetch_one(&mut *tx)
            .await?;
            Some(id)
        };
        // The records still needed start at the oldest one holding a sample not moved.
        let still_in_log = |stroke: &Uuid| !closed.contains(stroke) && !moved.contains(stroke);
        let oldest_needed = self
            .strokes
            .iter()
            .chain(&loaded)
            .filter(|(stroke, _)| still_in_log(stroke))
            .filter_map(|(_, known)| known.first_record)
            .chain(record_id.filter(|_| appended.keys().any(still_in_log)))
            .min();
        let low = oldest_needed.unwrap_or(record_id.unwrap_or(self.last_record) + 1);
        let trim = low - self.trimmed_below >= TRIM_RECORDS || move_all;
        if trim {
            sqlx::query("DELETE FROM stroke_log WHERE writer = $1 AND id < $2")
                .bind(self.writer_id)
                .bind(low)
                .execute(&mut *tx)
                .await?;
        }
        if backend == Backend::Postgres {
            let events: Vec<SessionEvent> = requests
                .iter()
                .zip(&refused)
                .filter(|(_, r)| r.is_none())
                .flat_map(|(req, _)| req.events.iter().cloned())
                .collect();
            if !events.is_empty() {
                notify(&mut tx, &events).await?;
            }
        }
        if fault == Some(Fault::Fail) {
            anyhow::bail!("injected failure before COMMIT");
        }
        tx.commit().await?;
        if fault == Some(Fault::FailAfterCommit) {
            anyhow::bail!("injected failure after COMMIT");
        }
        // What is committed now.
        if check_idle {
            self.idle_checked = Instant::now();
        }
        for (stroke, known) in loaded {
            self.strokes.entry(stroke).or_insert(known);
        }
        for stroke in begun {
            self.strokes.entry(stroke).or_default();
        }
        let at = Instant::now();
        for (stroke, samples) in appended {
            let known = self.strokes.entry(stroke).or_default();
            if known.pending.is_empty() {
                known.first_record = record_id;
                known.since = Some(at);
            }
            known.pending.extend(samples);
        }
        for stroke in moved {
            if let Some(known) = self.strokes.get_mut(&stroke) {
                known.chunk_end = known.end();
                known.pending = Vec::new();
                known.first_record = None;
                known.since = None;
            }
        }
        for stroke in closed {
            self.strokes.remove(&stroke);
        }
        if let Some(id) = record_id {
            self.last_record = id;
        }
        if trim {
            self.trimmed_below = low;
        }
        Ok(refused)
    }
}

fn timed_out(deadline: Duration) -> anyhow::Error {
    anyhow::anyhow!("the database did not answer within {} ms", deadline.as_millis())
}

/// Where `stroke_chunks` holds the samples of `stroke` up to (its rows are contiguous from 0;
/// rows may overlap where two writers moved the same samples).
async fn chunk_end(conn: &mut AnyConnection, stroke: Uuid) -> anyhow::Result<u64> {
    let rows = sqlx::query("SELECT seq, n FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq")
        .bind(stroke.to_string())
        .fetch_all(&mut *conn)
        .await?;
    let mut end = 0u64;
    for row in rows {
        let (seq, n) = (row.try_get::<i64, _>("seq")? as u64, row.try_get::<i64, _>("n")? as u64);
        anyhow::ensure!(seq <= end, "stroke {stroke}: chunk at seq {seq} follows {end} samples");
        end = end.max(seq + n);
    }
    Ok(end)
}

/// What is stored of `stroke`, read from the database: its chunks' end and the samples after
/// it in the log (any writer's); `None` when it has no row.
async fn load_stroke(
    conn: &mut AnyConnection,
    stroke: Uuid,
    writer: i64,
) -> anyhow::Result<Option<Known>> {
    if !log::stroke_exists(conn, stroke).await? {
        return Ok(None);
    }
    let chunk_end = chunk_end(conn, stroke).await?;
    let wanted = HashSet::from([stroke]);
    let entries =
        log::read_log(conn, Some(&wanted), None).await?.remove(&stroke).unwrap_or_default();
    known_from(stroke, chunk_end, entries, writer).map(Some)
}

/// The refusal of samples or an end of a stroke that does not exist.
fn no_stroke(stroke: Uuid) -> WriteError {
    WriteError::Refused(format!(
        "stroke {stroke} does not exist (its stroke_begin was not stored), so nothing of it \
         is; begin it again"
    ))
}

/// A stroke's state from its chunks' end and its log entries (id and writer of the record).
fn known_from(
    stroke: Uuid,
    chunk_end: u64,
    entries: Vec<(i64, i64, log::Entry)>,
    writer: i64,
) -> anyhow::Result<Known> {
    let beyond = |(_, _, e): &&(i64, i64, log::Entry)| e.seq + e.samples.len() as u64 > chunk_end;
    let first_record =
        entries.iter().filter(beyond).filter(|(_, w, _)| *w == writer).map(|(id, _, _)| *id).min();
    let pieces = entries.into_iter().map(|(_, _, e)| Piece { seq: e.seq, samples: e.samples });
    let pending = log::assemble_from(stroke, chunk_end, pieces.collect())?;
    let since = (!pending.is_empty()).then(Instant::now);
    Ok(Known { chunk_end, pending, first_record, since })
}

/// After a failed transaction: every stroke with samples in this writer's records, as stored.
/// Samples that cannot be moved into `stroke_chunks` (a stroke with no row, samples that do
/// not decode or do not fit together) are set aside (`log::set_aside`) and forgotten, so that
/// one bad stroke does not fail every transaction after it.
async fn recover(conn: &mut AnyConnection, writer: i64) -> anyhow::Result<HashMap<Uuid, Known>> {
    let mut strokes = HashMap::new();
    for (stroke, entries) in log::read_log_to_move(conn, Some(writer)).await? {
        let mut records: Vec<i64> = entries.iter().map(|(id, _, _)| *id).collect();
        records.dedup();
        let known = if log::stroke_exists(conn, stroke).await? {
            chunk_end(conn, stroke).await.and_then(|end| known_from(stroke, end, entries, writer))
        } else {
            Err(anyhow::anyhow!("stroke {stroke} has no row"))
        };
        match known {
            Ok(known) => {
                strokes.insert(stroke, known);
            }
            Err(err) if log::is_database_error(&err) => return Err(err),
            Err(err) => log::set_aside(conn, &records, Some(stroke), &format!("{err:#}")).await?,
        }
    }
    Ok(strokes)
}

/// Stores the simplified stroke, marks it `done`, and moves the rest of its samples (those
/// after its chunks: in the log, and this transaction's) into `stroke_chunks` as one row. A
/// stroke is one row when drawn in under [`MOVE_AFTER`], one more per [`MOVE_AFTER`] of
/// drawing otherwise. The rows already stored are not read back and rewritten into one: that
/// wrote every sample of a longer stroke twice, for a few bytes of row header saved.
async fn finish(
    conn: &mut AnyConnection,
    backend: Backend,
    stroke: Uuid,
    base: &Known,
    tail: &[Sample],
    kept: &[Kept],
    now: i64,
) -> anyhow::Result<()> {
    let mut samples = base.pending.clone();
    samples.extend_from_slice(tail);
    if !samples.is_empty() {
        insert_chunks(conn, backend, &[(stroke, base.chunk_end, &samples)]).await?;
    }
    let indices: Vec<u64> = kept.iter().map(|k| k.index as u64).collect();
    let kept_samples: Vec<Sample> = kept.iter().map(|k| k.sample).collect();
    let (layout, data) = encode_samples(&kept_samples);
    sqlx::query(
        "INSERT INTO simplified (stroke_id, indices, layout, data) VALUES ($1, $2, $3, $4) \
         ON CONFLICT (stroke_id) DO UPDATE SET indices = excluded.indices, \
         layout = excluded.layout, data = excluded.data, upto = NULL",
    )
    .bind(stroke.to_string())
    .bind(encode_indices(&indices))
    .bind(layout)
    .bind(data)
    .execute(&mut *conn)
    .await?;
    sqlx::query(
        "UPDATE strokes SET status = 'done', n_retained = $1, updated_at = $2 WHERE id = $3",
    )
    .bind(kept.len() as i64)
    .bind(now)
    .bind(stroke.to_string())
    .execute(&mut *conn)
    .await?;
    Ok(())
}

/// Most rows per multi-row `INSERT`. A group commit is a chain of round trips to the database
/// (with SQLite, to sqlx's worker thread), and when the cores are busy each round trip waits
/// for the scheduler, twice: under 500 pens a commit of 14 statements took 13 ms while SQLite
/// itself was busy a quarter of that. So a commit's moves go in as few statements as SQLite's
/// parameter limit allows (5 parameters per row, at most 32,766 per statement).
const MAX_ROWS_PER_STATEMENT: usize = 1024;
/// Statements of up to this many rows (and of exactly [`MAX_ROWS_PER_STATEMENT`]) stay in the
/// connection's prepared-statement cache: the shapes of a lightly loaded proxy. Other sizes are
/// prepared for one use, so that they do not push the common shapes out of the cache.
const CACHED_ROWS: usize = 16;

/// Rows of `stroke_chunks` (stroke, seq of the first sample, samples) as multi-row `INSERT`s
/// (see [`MAX_ROWS_PER_STATEMENT`]); pieces of one stroke that follow each other become one row.
///
/// SQLite gets positional `?` placeholders: sqlx's SQLite driver looks each numbered `$N` up by
/// name among all the statement's parameters, which is quadratic in their number.
async fn insert_chunks(
    conn: &mut AnyConnection,
    backend: Backend,
    appends: &[(Uuid, u64, &[Sample])],
) -> anyhow::Result<()> {
    use std::fmt::Write;
    // (stroke, seq of the first sample, samples), and where each stroke's last row is.
    let mut rows: Vec<(Uuid, u64, Vec<Sample>)> = Vec::new();
    let mut last_row: HashMap<Uuid, usize> = HashMap::new();
    for &(stroke, seq, samples) in appends {
        match last_row.get(&stroke) {
            Some(&i) if rows[i].1 + rows[i].2.len() as u64 == seq => {
                rows[i].2.extend_from_slice(samples)
            }
            _ => {
                last_row.insert(stroke, rows.len());
                rows.push((stroke, seq, samples.to_vec()));
            }
        }
    }
    for chunk in rows.chunks(MAX_ROWS_PER_STATEMENT) {
        let mut sql =
            String::from("INSERT INTO stroke_chunks (stroke_id, seq, n, layout, data) VALUES ");
        for k in 0..chunk.len() {
            let sep = if k == 0 { "" } else { ", " };
            match backend {
                Backend::Sqlite => {
                    let _ = write!(sql, "{sep}(?, ?, ?, ?, ?)");
                }
                Backend::Postgres => {
                    let p = 5 * k;
                    let _ = write!(
                        sql,
                        "{sep}(${}, ${}, ${}, ${}, ${})",
                        p + 1,
                        p + 2,
                        p + 3,
                        p + 4,
                        p + 5
                    );
                }
            }
        }
        // No `ON CONFLICT`: the writer only writes what is not stored (`WriterLoop::strokes`), so
        // a conflict is a wrong end, and failing makes the retry read the ends again.
        let cached = chunk.len() <= CACHED_ROWS || chunk.len() == MAX_ROWS_PER_STATEMENT;
        let mut query = sqlx::query(&sql).persistent(cached);
        for (stroke, seq, samples) in chunk {
            let (layout, data) = encode_samples(samples);
            query = query
                .bind(stroke.to_string())
                .bind(*seq as i64)
                .bind(samples.len() as i64)
                .bind(layout)
                .bind(data);
        }
        query.execute(&mut *conn).await?;
    }
    Ok(())
}

/// Stores a done stroke's mesh unless the meshes of its session would then hold more than
/// `quota` bytes: one statement, which sees the meshes this transaction wrote before it.
/// `Err`: refused, nothing written.
async fn put_mesh(
    conn: &mut AnyConnection,
    stroke: Uuid,
    session: Uuid,
    mesh: &MeshRow,
    quota: u64,
) -> anyhow::Result<Result<(), WriteError>> {
    // `length` of a blob is its size in bytes in both SQLite and PostgreSQL, read without
    // loading the blob.
    const OTHERS: &str = "SELECT COALESCE(SUM(length(m.glb)), 0) FROM meshes m \
         JOIN strokes s ON s.id = m.stroke_id WHERE s.session_id = $1 AND m.stroke_id <> $2";
    let written = sqlx::query(&format!(
        "INSERT INTO meshes (stroke_id, glb, vertices, triangles, uploader, created_at) \
         SELECT $2, $3, $4, $5, $6, $7 WHERE ({OTHERS}) + $8 <= $9 \
         ON CONFLICT (stroke_id) DO UPDATE SET glb = excluded.glb, vertices = excluded.vertices, \
         triangles = excluded.triangles, uploader = excluded.uploader, \
         created_at = excluded.created_at"
    ))
    .bind(session.to_string())
    .bind(stroke.to_string())
    .bind(mesh.glb.as_slice())
    .bind(mesh.vertices as i64)
    .bind(mesh.triangles as i64)
    .bind(mesh.uploader.clone())
    .bind(mesh.created_at)
    .bind(mesh.glb.len() as i64)
    .bind(i64::try_from(quota).unwrap_or(i64::MAX))
    .execute(&mut *conn)
    .await?;
    if written.rows_affected() > 0 {
        return Ok(Ok(()));
    }
    let others: i64 = sqlx::query_scalar(OTHERS)
        .bind(session.to_string())
        .bind(stroke.to_string())
        .fetch_one(&mut *conn)
        .await?;
    Ok(Err(WriteError::Quota(format!(
        "the meshes of this session hold {others} bytes (this stroke's own not counted); with \
         this one of {} bytes they would pass the session's quota of {quota} bytes",
        mesh.glb.len()
    ))))
}

/// Applies an op other than an append or a finish. `true`: it created a stroke.
async fn apply(conn: &mut AnyConnection, op: &WriteOp, now: i64) -> anyhow::Result<bool> {
    match op {
        WriteOp::BeginStroke { stroke, session, participant, brush, params, device } => {
            let created = sqlx::query(
                "INSERT INTO strokes (id, session_id, participant, brush, params, device, status, \
                 n_retained, created_at, updated_at) \
                 VALUES ($1, $2, $3, $4, $5, $6, 'open', 0, $7, $7) ON CONFLICT (id) DO NOTHING",
            )
            .bind(stroke.to_string())
            .bind(session.to_string())
            .bind(participant.to_string())
            .bind(serde_json::to_string(brush)?)
            .bind(serde_json::to_string(params)?)
            .bind(device.clone())
            .bind(now)
            .execute(&mut *conn)
            .await?;
            return Ok(created.rows_affected() == 1);
        }
        WriteOp::Append { .. } => anyhow::bail!("an append goes into the log record"),
        WriteOp::PutMesh { .. } => anyhow::bail!("a mesh is written where it is planned"),
        WriteOp::KeepRetained { stroke, upto, kept } => {
            let indices: Vec<u64> = kept.iter().map(|k| k.index as u64).collect();
            let samples: Vec<Sample> = kept.iter().map(|k| k.sample).collect();
            let (layout, data) = encode_samples(&samples);
            // Never over the simplified stroke of a done stroke (`upto` NULL), nor over what
            // covers more samples.
            sqlx::query(
                "INSERT INTO simplified (stroke_id, indices, layout, data, upto) \
                 VALUES ($1, $2, $3, $4, $5) ON CONFLICT (stroke_id) DO UPDATE SET \
                 indices = excluded.indices, layout = excluded.layout, data = excluded.data, \
                 upto = excluded.upto \
                 WHERE simplified.upto IS NOT NULL AND simplified.upto < excluded.upto",
            )
            .bind(stroke.to_string())
            .bind(encode_indices(&indices))
            .bind(layout)
            .bind(data)
            .bind(*upto as i64)
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::Finish { .. } => anyhow::bail!("a finish goes through `finish`"),
        WriteOp::Join { connection, participant, session, name, replica } => {
            sqlx::query(
                "INSERT INTO participants (connection, participant, session_id, name, joined_at, \
                 replica_key) VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (connection) DO NOTHING",
            )
            .bind(connection.to_string())
            .bind(participant.to_string())
            .bind(session.to_string())
            .bind(name.clone())
            .bind(now)
            .bind(*replica)
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::Leave { connection } => {
            sqlx::query(
                "UPDATE participants SET left_at = $1 WHERE connection = $2 AND left_at IS NULL",
            )
            .bind(now)
            .bind(connection.to_string())
            .execute(&mut *conn)
            .await?;
        }
        WriteOp::SetStatus { stroke, status } => {
            sqlx::query(
                "UPDATE strokes SET status = $1, updated_at = $2 WHERE id = $3 AND status <> 'done'",
            )
            .bind(status.as_str())
            .bind(now)
            .bind(stroke.to_string())
            .execute(&mut *conn)
            .await?;
        }
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn append(n: usize) -> Vec<WriteOp> {
        let samples = vec![Sample::new(0.0, 0.0, 0.0, 0.5); n];
        vec![WriteOp::Append { stroke: Uuid::new_v4(), seq: 0, samples }]
    }

    #[tokio::test]
    async fn the_bytes_queued_into_the_writer_are_bounded() {
        let (tx, mut rx) = mpsc::channel(100);
        let sample = std::mem::size_of::<Sample>();
        let writer = Writer { tx, bytes: None }.limit_bytes(4 * sample);
        // Three samples fit, a fourth fits, a fifth waits: the count alone (100) would take it.
        let _first = writer.submit(append(3)).await;
        let _second = writer.submit(append(1)).await;
        let waits = tokio::time::timeout(Duration::from_millis(100), writer.submit(append(1)));
        assert!(waits.await.is_err(), "queued past the byte limit");
        // Once the writer is done with a request its bytes are free again.
        drop(rx.recv().await.unwrap());
        let goes = tokio::time::timeout(Duration::from_secs(5), writer.submit(append(1)));
        assert!(goes.await.is_ok());
        // A request larger than the whole limit goes in alone instead of waiting forever.
        while let Ok(request) = rx.try_recv() {
            drop(request);
        }
        let huge = tokio::time::timeout(Duration::from_secs(5), writer.submit(append(100)));
        assert!(huge.await.is_ok());
    }
}
