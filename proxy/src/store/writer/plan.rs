//! Planning a transaction: each request's ops checked against where its strokes' stored samples
//! end, and the request written whole ([`Planned`]: an append trimmed to what is not stored
//! yet) or refused whole (a hole, samples after the stroke's end, a stroke that does not exist,
//! a mesh past its session's quota).

use std::collections::{HashMap, HashSet};

use penmesh::Sample;
use sqlx::AnyConnection;
use uuid::Uuid;

use super::known::{Known, load_stroke};
use super::sql::{put_mesh, session_samples};
use super::{WriteError, WriteOp, WriteRequest, closes, sharing};
use crate::store::log;

/// An op as it will be written: an append trimmed to what is not stored yet.
pub(super) enum Planned<'a> {
    Append { stroke: Uuid, seq: u64, samples: &'a [Sample] },
    Other(&'a WriteOp),
}

/// A transaction's plan.
#[derive(Default)]
pub(super) struct Plan<'a> {
    /// The ops to write, in order.
    pub(super) ops: Vec<Planned<'a>>,
    /// For each request, why it was refused, or `None`: planned.
    pub(super) refused: Vec<Option<WriteError>>,
    /// Strokes read from the database in this transaction.
    pub(super) loaded: HashMap<Uuid, Known>,
    /// The strokes it closes (moved out of the log and forgotten once it commits).
    pub(super) closed: Vec<Uuid>,
    /// The ends of the strokes as it leaves them.
    ends: HashMap<Uuid, u64>,
    /// Strokes it creates: they have no row yet, and exist once it commits.
    creates: HashSet<Uuid>,
    /// Per session, its stored samples and those its planned requests count
    /// ([`WriteOp::CountSamples`]), read from the database on first use.
    session_samples: HashMap<Uuid, u64>,
}

/// One request's plan, kept apart until it is known not to be refused (reused: a group commit
/// plans hundreds of requests).
#[derive(Default)]
struct RequestPlan<'a> {
    ends: HashMap<Uuid, u64>,
    ops: Vec<Planned<'a>>,
    creates: HashSet<Uuid>,
    /// The samples it counts, by session.
    counted: Vec<(Uuid, u64)>,
}

impl<'a> Plan<'a> {
    /// Plans `requests` in order against what the writer knows (`known`) and, for strokes it
    /// does not know, what `tx` holds. A mesh is written here, as only the write tells whether
    /// it fits its quota.
    pub(super) async fn make(
        tx: &mut AnyConnection,
        requests: &[&'a WriteRequest],
        known: &HashMap<Uuid, Known>,
        writer: i64,
    ) -> anyhow::Result<Plan<'a>> {
        let mut plan = Plan::default();
        plan.refused.reserve(requests.len());
        let mut req_plan = RequestPlan::default();
        for req in requests {
            // A request is written whole or refused whole.
            req_plan.ends.clear();
            req_plan.ops.clear();
            req_plan.creates.clear();
            req_plan.counted.clear();
            let refusal = plan.request(tx, req, &mut req_plan, known, writer).await?;
            if refusal.is_none() {
                plan.ops.append(&mut req_plan.ops);
                plan.ends.extend(req_plan.ends.drain());
                plan.creates.extend(req_plan.creates.drain());
                for (session, n) in req_plan.counted.drain(..) {
                    *plan.session_samples.entry(session).or_default() += n;
                }
            }
            plan.refused.push(refusal);
        }
        Ok(plan)
    }

    /// Plans the ops of `req` into `req_plan`, up to the first refused (`Some`: why).
    async fn request(
        &mut self,
        tx: &mut AnyConnection,
        req: &'a WriteRequest,
        req_plan: &mut RequestPlan<'a>,
        known: &HashMap<Uuid, Known>,
        writer: i64,
    ) -> anyhow::Result<Option<WriteError>> {
        for op in &req.ops {
            let refusal = match op {
                WriteOp::PutMesh { stroke, session, mesh, solid, quota } => {
                    put_mesh(tx, (*stroke, *session), mesh, *solid, *quota).await?.err()
                }
                WriteOp::Append { stroke, seq, samples } => {
                    self.append(tx, (*stroke, *seq, samples), req_plan, known, writer).await?
                }
                _ => self.other(tx, op, req_plan, known, writer).await?,
            };
            if refusal.is_some() {
                return Ok(refusal);
            }
        }
        Ok(None)
    }

    /// Plans an op other than an append or a mesh. A `Finish` of a stroke that does not exist
    /// is refused.
    async fn other(
        &mut self,
        tx: &mut AnyConnection,
        op: &'a WriteOp,
        req_plan: &mut RequestPlan<'a>,
        known: &HashMap<Uuid, Known>,
        writer: i64,
    ) -> anyhow::Result<Option<WriteError>> {
        match op {
            WriteOp::BeginStroke { stroke, .. } => {
                req_plan.creates.insert(*stroke);
            }
            WriteOp::Claim { stroke } => {
                let taken = known.contains_key(stroke)
                    || self.loaded.contains_key(stroke)
                    || self.creates.contains(stroke)
                    || req_plan.creates.contains(stroke)
                    || log::stroke_exists(tx, *stroke).await?;
                if taken {
                    return Ok(Some(WriteError::Taken(format!(
                        "stroke id {stroke} is taken; choose a new random id"
                    ))));
                }
            }
            WriteOp::CountSamples { session, samples, quota } => {
                let stored = match self.session_samples.get(session) {
                    Some(&n) => n,
                    None => {
                        let n = session_samples(tx, *session).await?;
                        self.session_samples.insert(*session, n);
                        n
                    }
                };
                let counted: u64 =
                    req_plan.counted.iter().filter(|(s, _)| s == session).map(|(_, n)| n).sum();
                if stored + counted + samples > *quota {
                    return Ok(Some(WriteError::Quota(format!(
                        "the session's strokes hold {} samples; {samples} more would pass its \
                         quota of {quota} samples (--max-session-samples)",
                        stored + counted
                    ))));
                }
                req_plan.counted.push((*session, *samples));
            }
            WriteOp::MarkDuplicate { source, shares: Some(solid), .. } => {
                let now = sharing::current_solid(tx, *source).await?;
                if now != *solid {
                    return Ok(Some(WriteError::Refused(format!(
                        "stroke {source} became {now} while it was being duplicated as {solid}: \
                         duplicate it again"
                    ))));
                }
            }
            // A stroke exists before anything of it is stored.
            WriteOp::Finish { stroke, .. }
                if !known.contains_key(stroke)
                    && !self.loaded.contains_key(stroke)
                    && !self.creates.contains(stroke)
                    && !req_plan.creates.contains(stroke) =>
            {
                match load_stroke(tx, *stroke, writer).await? {
                    Some(found) => {
                        self.loaded.insert(*stroke, found);
                    }
                    None => return Ok(Some(no_stroke(*stroke))),
                }
            }
            _ => {}
        }
        self.closed.extend(closes(op));
        req_plan.ops.push(Planned::Other(op));
        Ok(None)
    }

    /// Plans the append of `samples` at `seq` to `stroke`: only where the stroke's stored
    /// samples end, trimmed to what is not stored yet.
    async fn append(
        &mut self,
        tx: &mut AnyConnection,
        (stroke, seq, samples): (Uuid, u64, &'a [Sample]),
        req_plan: &mut RequestPlan<'a>,
        known: &HashMap<Uuid, Known>,
        writer: i64,
    ) -> anyhow::Result<Option<WriteError>> {
        if self.closed.contains(&stroke) {
            return Ok(Some(WriteError::Refused(format!(
                "samples of stroke {stroke} after its end in the same request"
            ))));
        }
        let end = req_plan
            .ends
            .get(&stroke)
            .or_else(|| self.ends.get(&stroke))
            .copied()
            .or_else(|| known.get(&stroke).map(Known::end))
            .or_else(|| self.loaded.get(&stroke).map(Known::end));
        let end = match end {
            Some(end) => end,
            None => match load_stroke(tx, stroke, writer).await? {
                Some(found) => {
                    let end = found.end();
                    self.loaded.insert(stroke, found);
                    end
                }
                None if self.creates.contains(&stroke) || req_plan.creates.contains(&stroke) => {
                    self.loaded.insert(stroke, Known::default());
                    0
                }
                // Its begin failed (or never came): nothing of it is stored or acked.
                None => return Ok(Some(no_stroke(stroke))),
            },
        };
        let upto = seq + samples.len() as u64;
        if seq > end {
            return Ok(Some(WriteError::Refused(format!(
                "samples {seq}..{upto} of stroke {stroke} would leave a hole: only {end} are \
                 stored"
            ))));
        }
        if upto > end {
            let samples = &samples[(end - seq) as usize..];
            req_plan.ops.push(Planned::Append { stroke, seq: end, samples });
        }
        req_plan.ends.insert(stroke, end.max(upto));
        Ok(None)
    }

    /// This transaction's appends by stroke, for the moves.
    pub(super) fn appended(&self) -> HashMap<Uuid, Vec<Sample>> {
        let mut appended: HashMap<Uuid, Vec<Sample>> = HashMap::new();
        for op in &self.ops {
            if let Planned::Append { stroke, samples, .. } = op {
                appended.entry(*stroke).or_default().extend_from_slice(samples);
            }
        }
        appended
    }

    /// This transaction's appends in order, as `(stroke, seq, samples)`: its log record.
    pub(super) fn record(&self) -> Vec<(Uuid, u64, &'a [Sample])> {
        let appends = self.ops.iter().filter_map(|op| match op {
            Planned::Append { stroke, seq, samples } => Some((*stroke, *seq, *samples)),
            Planned::Other(_) => None,
        });
        appends.collect()
    }
}

/// The refusal of samples or an end of a stroke that does not exist.
pub(super) fn no_stroke(stroke: Uuid) -> WriteError {
    WriteError::Refused(format!(
        "stroke {stroke} does not exist (its stroke_begin was not stored), so nothing of it \
         is; begin it again"
    ))
}
