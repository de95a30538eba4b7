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

#[cfg(feature = "fault-injection")]
mod faults;
mod known;
mod ops;
mod plan;
mod queue;
mod sharing;
mod sql;
mod transaction;

use std::collections::HashMap;
#[cfg(feature = "fault-injection")]
use std::sync::Arc;
use std::time::{Duration, Instant};

use sqlx::AnyConnection;
use tokio::sync::{mpsc, oneshot};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

#[cfg(feature = "fault-injection")]
pub use faults::{CommitFaults, Fault};
/// Failures to inject into the writer's transactions: only in builds with the
/// `fault-injection` feature (the tests'), none in any other.
#[cfg(feature = "fault-injection")]
pub type InjectedFaults = Option<Arc<CommitFaults>>;
/// Failures to inject into the writer's transactions: none without the `fault-injection`
/// feature (`None` is the only value).
#[cfg(not(feature = "fault-injection"))]
pub type InjectedFaults = Option<std::convert::Infallible>;
use known::Known;
pub use ops::{WriteError, WriteOp};
use queue::WriteRequest;
pub use queue::{Committed, PlacementIds, Writer};

use super::{Backend, Store};
use crate::events::SessionEvent;
use crate::fanout::Fanout;
use crate::stages::{self, Stage};

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
        faults: InjectedFaults,
        writer_id: Option<i64>,
    ) -> anyhow::Result<(Writer, WriterTask)> {
        let (tx, rx) = mpsc::channel(queue.max(1));
        #[cfg(not(feature = "fault-injection"))]
        let None = faults;
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
                        #[cfg(feature = "fault-injection")]
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
    #[cfg(feature = "fault-injection")]
    faults: Option<Arc<CommitFaults>>,
}

/// Records are deleted from the front of the log when this many can go at once (a delete
/// dirties the pages it frees; fewer, larger deletes dirty each page once).
const TRIM_RECORDS: i64 = 64;

/// How often the writer looks for strokes to move because they sat in the log long enough.
const IDLE_CHECK: Duration = Duration::from_millis(100);

/// The stroke a `Finish`, `SetStatus` or `CopySamples` closes: its samples leave the log, it
/// leaves the writer.
fn closes(op: &WriteOp) -> Option<Uuid> {
    match op {
        WriteOp::Finish { stroke, .. }
        | WriteOp::SetStatus { stroke, .. }
        | WriteOp::CopySamples { stroke, .. } => Some(*stroke),
        _ => None,
    }
}

/// Most bytes of meshes one transaction writes (more go in the next): what a mesh upload may
/// add to the commit of everyone's samples that shares its transaction.
const MESH_BYTES_PER_COMMIT: usize = 16 << 20;

/// Most samples one transaction copies in the database (duplicates; more go in the next): what
/// a duplicate of a long stroke may add to the commit of everyone's samples that shares its
/// transaction.
const COPIED_SAMPLES_PER_COMMIT: u64 = 1_000_000;

/// How many of `batch`'s requests go in one transaction: up to (not including) the first that
/// appends to a stroke an earlier request closed, so that a transaction moves a stroke out of
/// the log after all of its appends, or that would take the meshes past
/// [`MESH_BYTES_PER_COMMIT`] or the copies past [`COPIED_SAMPLES_PER_COMMIT`].
fn first_group(batch: &[WriteRequest]) -> usize {
    let mut closed = std::collections::HashSet::new();
    let mut mesh_bytes = 0;
    let mut copied = 0;
    for (i, req) in batch.iter().enumerate() {
        let reopens = req
            .ops
            .iter()
            .any(|op| matches!(op, WriteOp::Append { stroke, .. } if closed.contains(stroke)));
        mesh_bytes += req.ops.iter().map(WriteOp::mesh_bytes).sum::<usize>();
        copied += req.ops.iter().map(WriteOp::copied_samples).sum::<u64>();
        let full = mesh_bytes > MESH_BYTES_PER_COMMIT || copied > COPIED_SAMPLES_PER_COMMIT;
        if (reopens || full) && i > 0 {
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
        if let Err(err) = self.commit(&mut [], true).await {
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
        let mut all: Vec<&mut WriteRequest> = batch.iter_mut().collect();
        let result = stages::timed(Stage::Commit, self.commit(&mut all, false)).await;
        metrics::histogram!("penmesh_commit_seconds").record(started.elapsed().as_secs_f64());
        metrics::histogram!("penmesh_commit_batch_requests").record(batch.len() as f64);
        metrics::histogram!("penmesh_commit_batch_samples").record(n_samples as f64);
        match result {
            Ok(refused) => {
                let publishing = stages::start();
                for (req, refusal) in batch.drain(..).zip(refused) {
                    self.answer(req, refusal.map_or(Ok(()), Err));
                }
                publishing.stop(Stage::Publish);
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
                for mut req in batch.drain(..) {
                    let result = match self.commit(&mut [&mut req], false).await {
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
        let WriteRequest { events, placed, done, .. } = req;
        match &result {
            Ok(()) => self.publish(events),
            Err(_) => {
                metrics::counter!("penmesh_commit_failures_total").increment(1);
            }
        }
        let _ = done.send(result.map(|()| placed));
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
        requests: &mut [&mut WriteRequest],
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
}

fn timed_out(deadline: Duration) -> anyhow::Error {
    anyhow::anyhow!("the database did not answer within {} ms", deadline.as_millis())
}
