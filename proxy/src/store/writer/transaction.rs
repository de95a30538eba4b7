//! One transaction of the writer, in named steps: plan the requests ([`Plan`]), write the ops
//! that are not appends, move strokes out of the log, write the appends as one log record,
//! trim the log, queue the events (PostgreSQL), commit, and only then learn what is stored.

use std::collections::HashMap;
use std::time::Instant;

use penmesh::Sample;
use sqlx::{AnyConnection, Connection};
use uuid::Uuid;

#[cfg(feature = "fault-injection")]
use super::Fault;
use super::known::{Known, load_stroke, recover};
use super::plan::{Plan, Planned};
use super::sql::{apply, finish, insert_chunks, place};
use super::{IDLE_CHECK, TRIM_RECORDS, WriteError, WriteOp, WriteRequest, WriterLoop};
use crate::events::SessionEvent;
use crate::store::log::{self, MOVE_AFTER};
use crate::store::{Backend, notify, now_ms};

/// What a transaction wrote, for the writer to know once it commits.
struct Written {
    /// Strokes read from the database in the transaction.
    loaded: HashMap<Uuid, Known>,
    /// Strokes it created: nothing of them is stored before it.
    begun: Vec<Uuid>,
    /// Its appends, by stroke.
    appended: HashMap<Uuid, Vec<Sample>>,
    /// Strokes it moved out of the log because they sat there long enough.
    moved: Vec<Uuid>,
    /// Strokes it closed.
    closed: Vec<Uuid>,
    /// Its log record, if it appended anything.
    record_id: Option<i64>,
    /// This writer's records below this id were deleted.
    trimmed_below: Option<i64>,
    /// It looked for strokes that sat in the log long enough.
    idle_checked: bool,
}

impl WriterLoop {
    /// One transaction of `requests` (see [`WriterLoop::commit`], which bounds it in time and
    /// forgets what the writer knew when it fails).
    pub(super) async fn try_commit(
        &mut self,
        requests: &mut [&mut WriteRequest],
        move_all: bool,
    ) -> anyhow::Result<Vec<Option<WriteError>>> {
        self.idle_moved = false;
        // Read while planned and written; numbered (their placements' ids) once written.
        let planned: Vec<&WriteRequest> = requests.iter().map(|r| &**r).collect();
        #[cfg(feature = "fault-injection")]
        let fault = self.faults.as_ref().and_then(|f| f.hit(&planned));
        // Taken for the transaction, given back once it commits: one that failed is dropped.
        let mut conn = match self.conn.take() {
            Some(conn) => conn,
            None => {
                let conn = self.store.open_write_connection().await?;
                tracing::warn!("the write connection is open again");
                conn
            }
        };
        let mut tx = conn.begin_with(self.begin).await?;
        if self.recover {
            // Valid whether or not this transaction commits: it is what is committed now.
            self.strokes = recover(&mut tx, self.writer_id).await?;
            self.recover = false;
        }
        let now = now_ms();
        let plan = Plan::make(&mut tx, &planned, &self.strokes, self.writer_id).await?;
        let (appended, record) = (plan.appended(), plan.record());
        let (begun, mut moves, placed) = self.write_ops(&mut tx, &plan, &appended, now).await?;
        // Strokes that sat in the log long enough move too (all of them when stopping).
        let idle_checked = move_all || self.idle_checked.elapsed() >= IDLE_CHECK;
        let moved = match idle_checked {
            true => self.idle_moves(&plan, &appended, move_all, &mut moves),
            false => Vec::new(),
        };
        let rows: Vec<(Uuid, u64, &[Sample])> =
            moves.iter().map(|(s, seq, samples)| (*s, *seq, samples.as_slice())).collect();
        insert_chunks(&mut tx, self.store.backend(), &rows).await?;
        let record_id = self.write_record(&mut tx, &record).await?;
        let Plan { refused, loaded, closed, .. } = plan;
        let mut placed = placed.into_iter();
        for (req, _) in requests.iter_mut().zip(&refused).filter(|(_, r)| r.is_none()) {
            req.number_placements(&mut placed);
        }
        let written = Written {
            loaded,
            begun,
            appended,
            moved,
            closed,
            record_id,
            trimmed_below: None,
            idle_checked,
        };
        let trimmed_below = self.trim(&mut tx, &written, move_all).await?;
        if self.store.backend() == Backend::Postgres {
            notify_committed(&mut tx, &*requests, &refused, self.fanout.tag()).await?;
        }
        #[cfg(feature = "fault-injection")]
        if fault == Some(Fault::Fail) {
            anyhow::bail!("injected failure before COMMIT");
        }
        tx.commit().await?;
        #[cfg(feature = "fault-injection")]
        if fault == Some(Fault::FailAfterCommit) {
            anyhow::bail!("injected failure after COMMIT");
        }
        self.conn = Some(conn);
        self.learn(Written { trimmed_below, ..written });
        Ok(refused)
    }

    /// Writes the planned ops other than appends, in order. `Finish` moves its stroke out of
    /// the log itself; `SetStatus` adds its stroke's samples in the log to `moves`. Returns the
    /// strokes created, `moves`, and the ids of the placements inserted, in order.
    async fn write_ops(
        &self,
        tx: &mut AnyConnection,
        plan: &Plan<'_>,
        appended: &HashMap<Uuid, Vec<Sample>>,
        now: i64,
    ) -> anyhow::Result<(Vec<Uuid>, Vec<(Uuid, u64, Vec<Sample>)>, Vec<i64>)> {
        let backend = self.store.backend();
        let mut begun: Vec<Uuid> = Vec::new();
        let mut placed: Vec<i64> = Vec::new();
        let mut moves: Vec<(Uuid, u64, Vec<Sample>)> = Vec::new();
        // Strokes claimed as new ids (`WriteOp::Claim`).
        let mut claimed: Vec<Uuid> = Vec::new();
        for op in &plan.ops {
            let Planned::Other(op) = op else { continue };
            match op {
                WriteOp::Finish { stroke, kept } => {
                    // Known, or created by this transaction (checked when planned).
                    let base = match self.strokes.get(stroke).or_else(|| plan.loaded.get(stroke)) {
                        Some(known) => known.clone(),
                        None => load_stroke(tx, *stroke, self.writer_id).await?.unwrap_or_default(),
                    };
                    let tail = appended.get(stroke).map(Vec::as_slice).unwrap_or_default();
                    finish(tx, backend, *stroke, &base, tail, kept, now).await?;
                }
                WriteOp::SetStatus { stroke, .. } => {
                    let known = self.strokes.get(stroke).or_else(|| plan.loaded.get(stroke));
                    if let Some(known) = known {
                        let mut samples = known.pending.clone();
                        samples.extend(appended.get(stroke).into_iter().flatten());
                        if !samples.is_empty() {
                            moves.push((*stroke, known.chunk_end, samples));
                        }
                    }
                    apply(tx, op, now).await?;
                }
                WriteOp::Claim { stroke } => claimed.push(*stroke),
                WriteOp::BeginStroke { stroke, .. } => {
                    if apply(tx, op, now).await? {
                        begun.push(*stroke);
                    } else if claimed.contains(stroke) {
                        // Another writer (a replica) created it since it was planned: this
                        // transaction fails, and the request alone is planned again, refused.
                        anyhow::bail!("claimed stroke {stroke} was created meanwhile");
                    }
                }
                WriteOp::Place { .. } => placed.push(place(tx, op).await?),
                _ => {
                    apply(tx, op, now).await?;
                }
            }
        }
        Ok((begun, moves, placed))
    }

    /// Adds to `moves` the strokes not closed by the plan whose samples sat in the log for
    /// [`MOVE_AFTER`] (all of them with `move_all`), and returns them.
    fn idle_moves(
        &mut self,
        plan: &Plan<'_>,
        appended: &HashMap<Uuid, Vec<Sample>>,
        move_all: bool,
        moves: &mut Vec<(Uuid, u64, Vec<Sample>)>,
    ) -> Vec<Uuid> {
        let mut moved: Vec<Uuid> = Vec::new();
        let due = |k: &Known| move_all || k.since.is_some_and(|t| t.elapsed() >= MOVE_AFTER);
        for (stroke, known) in self.strokes.iter().chain(&plan.loaded) {
            if plan.closed.contains(stroke) || !due(known) {
                continue;
            }
            let mut samples = known.pending.clone();
            samples.extend(appended.get(stroke).into_iter().flatten());
            moved.push(*stroke);
            moves.push((*stroke, known.chunk_end, samples));
        }
        self.idle_moved = !moved.is_empty();
        moved
    }

    /// The appends as one record of the log; its id, `None` when there are none.
    async fn write_record(
        &self,
        tx: &mut AnyConnection,
        record: &[(Uuid, u64, &[Sample])],
    ) -> anyhow::Result<Option<i64>> {
        if record.is_empty() {
            return Ok(None);
        }
        let id: i64 = sqlx::query_scalar(
            "INSERT INTO stroke_log (writer, data) VALUES ($1, $2) RETURNING id",
        )
        .bind(self.writer_id)
        .bind(log::encode_record(record))
        .fetch_one(&mut *tx)
        .await?;
        Ok(Some(id))
    }

    /// Deletes this writer's records that hold no sample still needed, once
    /// [`TRIM_RECORDS`] of them can go (all with `move_all`). Returns the new low end, if it
    /// deleted.
    async fn trim(
        &self,
        tx: &mut AnyConnection,
        written: &Written,
        move_all: bool,
    ) -> anyhow::Result<Option<i64>> {
        // The records still needed start at the oldest one holding a sample not moved.
        let still_in_log =
            |stroke: &Uuid| !written.closed.contains(stroke) && !written.moved.contains(stroke);
        let oldest_needed = self
            .strokes
            .iter()
            .chain(&written.loaded)
            .filter(|(stroke, _)| still_in_log(stroke))
            .filter_map(|(_, known)| known.first_record)
            .chain(written.record_id.filter(|_| written.appended.keys().any(still_in_log)))
            .min();
        let low = oldest_needed.unwrap_or(written.record_id.unwrap_or(self.last_record) + 1);
        if low - self.trimmed_below < TRIM_RECORDS && !move_all {
            return Ok(None);
        }
        sqlx::query("DELETE FROM stroke_log WHERE writer = $1 AND id < $2")
            .bind(self.writer_id)
            .bind(low)
            .execute(&mut *tx)
            .await?;
        Ok(Some(low))
    }

    /// What is committed now: the strokes the writer appends to, as stored.
    fn learn(&mut self, written: Written) {
        if written.idle_checked {
            self.idle_checked = Instant::now();
        }
        for (stroke, known) in written.loaded {
            self.strokes.entry(stroke).or_insert(known);
        }
        for stroke in written.begun {
            self.strokes.entry(stroke).or_default();
        }
        let at = Instant::now();
        for (stroke, samples) in written.appended {
            let known = self.strokes.entry(stroke).or_default();
            if known.pending.is_empty() {
                known.first_record = written.record_id;
                known.since = Some(at);
            }
            known.pending.extend(samples);
        }
        for stroke in written.moved {
            if let Some(known) = self.strokes.get_mut(&stroke) {
                known.chunk_end = known.end();
                known.pending = Vec::new();
                known.first_record = None;
                known.since = None;
            }
        }
        for stroke in written.closed {
            self.strokes.remove(&stroke);
        }
        if let Some(id) = written.record_id {
            self.last_record = id;
        }
        if let Some(low) = written.trimmed_below {
            self.trimmed_below = low;
        }
    }
}

/// PostgreSQL: the events of the requests not refused, as notifications of the transaction,
/// each with its origin on this replica (tagged `replica`).
async fn notify_committed(
    tx: &mut AnyConnection,
    requests: &[&mut WriteRequest],
    refused: &[Option<WriteError>],
    replica: u64,
) -> anyhow::Result<()> {
    let events: Vec<SessionEvent> = requests
        .iter()
        .zip(refused)
        .filter(|(_, r)| r.is_none())
        .flat_map(|(req, _)| req.events.iter().map(|event| event.to_notify(replica)))
        .collect();
    if !events.is_empty() {
        notify(tx, &events).await?;
    }
    Ok(())
}
