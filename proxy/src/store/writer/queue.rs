//! The writer's queue: [`Writer`], the sending side every connection holds (bounded in requests
//! and in bytes of samples), and [`Committed`], the answer a request waits for.

use std::sync::Arc;

use tokio::sync::{mpsc, oneshot};

use super::{WriteError, WriteOp};
use crate::events::{EventKind, SessionEvent};

/// What a committed request learns that only the database could tell: the ids of the
/// `stroke_placements` rows its `Place` ops inserted, in their order.
pub type PlacementIds = Vec<i64>;

/// The answer to a submitted request: ready once it is committed (or failed). A named type, not
/// a boxed future, so that a connection keeps its requests in a plain queue (one allocation
/// less per batch, `ws::connection`).
#[derive(Debug)]
pub struct Committed {
    /// `None`: the request never reached the writer.
    pub(super) answer: Option<oneshot::Receiver<Result<PlacementIds, WriteError>>>,
}

impl Future for Committed {
    type Output = Result<PlacementIds, WriteError>;

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

pub(super) struct WriteRequest {
    pub(super) ops: Vec<WriteOp>,
    pub(super) events: Vec<SessionEvent>,
    /// Set once its `Place` ops are written ([`WriteRequest::number_placements`]).
    pub(super) placed: PlacementIds,
    pub(super) done: oneshot::Sender<Result<PlacementIds, WriteError>>,
    /// The request's share of the queue's bytes, given back when the request is dropped.
    pub(super) _bytes: Option<tokio::sync::OwnedSemaphorePermit>,
}

/// The sending side, cloned into every connection.
#[derive(Debug, Clone)]
pub struct Writer {
    pub(super) tx: mpsc::Sender<WriteRequest>,
    /// Bytes of samples queued or being committed, at most the semaphore's size (none: no
    /// limit but the count).
    pub(super) bytes: Option<(Arc<tokio::sync::Semaphore>, u32)>,
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
        let request = WriteRequest { ops, events, placed: Vec::new(), done, _bytes: bytes };
        let queued = self.tx.send(request).await.is_ok();
        Committed { answer: queued.then_some(rx) }
    }

    /// Queues `ops` and waits for the commit.
    pub async fn write(&self, ops: Vec<WriteOp>) -> Result<(), WriteError> {
        self.submit(ops).await.await.map(drop)
    }

    /// Queues `ops` with their `events` and waits for the commit.
    pub async fn write_with(
        &self,
        ops: Vec<WriteOp>,
        events: Vec<SessionEvent>,
    ) -> Result<(), WriteError> {
        self.submit_with(ops, events).await.await.map(drop)
    }
}

impl WriteRequest {
    /// Numbers the request's placements with the ids of the rows its `Place` ops inserted
    /// (taken from `ids`, every `Place` of the transaction in order): each `Placed` event
    /// gets the id of its stroke's next `Place`, so that the fan-out can tell an older
    /// placement from a newer one.
    pub(super) fn number_placements(&mut self, ids: &mut impl Iterator<Item = i64>) {
        let mut rows: Vec<(uuid::Uuid, i64)> = Vec::new();
        for op in &self.ops {
            if let WriteOp::Place { stroke, .. } = op {
                rows.extend(ids.next().map(|id| (*stroke, id)));
            }
        }
        self.placed = rows.iter().map(|(_, id)| *id).collect();
        for event in &mut self.events {
            if let EventKind::Placed { stroke, id, .. } = &mut event.kind
                && let Some(k) = rows.iter().position(|(s, _)| s == stroke)
            {
                *id = rows.remove(k).1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use penmesh::Sample;
    use uuid::Uuid;

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
