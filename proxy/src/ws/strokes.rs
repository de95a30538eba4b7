//! The stroke lifecycle on one connection: begin (or resume), points, end, and the answers
//! once the writer has committed them (`Ack` after commit, never before).

use std::collections::HashSet;
use std::time::Duration;

use penmesh::protocol::{
    Ack, ErrorCode, ParticipantId, PointBatch, Points, ResumeState, Retained, ServerMessage,
    StrokeBegin, StrokeDone, StrokeEnd, StrokeId, StrokeStatus, check_text,
};
use penmesh::{Kept, Sample};

use super::connection::{AfterCommit, Connection, Decided, Gathered};
use super::error::ConnError;
use crate::events::{EventKind, SessionEvent};
use crate::ingest::{Accepted, Finished, StrokeLimits, StrokeState};
use crate::stages::{self, Stage};
use crate::store::{PlacementIds, StrokeRow, WriteError, WriteOp};

/// The strokes a client drew before (and retained samples to send again), from `Hello.resume`.
type Resumed = (Vec<ResumeState>, Vec<(StrokeId, Vec<Kept>)>);

impl Connection {
    fn limits(&self) -> StrokeLimits {
        StrokeLimits {
            max_batch_samples: self.state.config.max_batch_samples,
            max_stroke_samples: self.state.config.max_stroke_samples,
            max_stroke_retained: self.state.config.max_stroke_retained,
        }
    }

    fn claim_wait(&self) -> Duration {
        Duration::from_millis(self.state.config.claim_wait_ms)
    }

    fn conflict(stroke: StrokeId) -> ConnError {
        ConnError::refused(
            ErrorCode::StrokeConflict,
            format!("stroke {stroke} is being drawn on another connection"),
            Some(stroke),
        )
    }

    /// Takes over the strokes of `Hello.resume` that are not done (up to the open-stroke
    /// limit): what `Welcome.resume` says of each, and the samples retained so far to send
    /// again. A stroke that cannot be taken is reported with an error, and as it is stored.
    pub(super) async fn resume_strokes(&mut self, wanted: Vec<StrokeId>) -> Resumed {
        let mut resume = Vec::with_capacity(wanted.len());
        let mut resent = Vec::new();
        let mut seen = HashSet::new();
        for stroke in wanted.into_iter().filter(|s| seen.insert(*s)) {
            let row = match self.state.store.stroke(stroke).await {
                Ok(row) => row.filter(|row| row.session_id == self.session),
                Err(err) => {
                    self.fail(ConnError::internal(
                        "reading a stroke to resume",
                        err,
                        "could not read the stroke",
                        Some(stroke),
                    ));
                    None
                }
            };
            let Some(row) = row else {
                resume.push(ResumeState { stroke, next_seq: 0, status: StrokeStatus::Unknown });
                continue;
            };
            let mut status = row.status;
            let mut next_seq = row.n_points;
            if status != StrokeStatus::Done
                && self.strokes.len() < self.state.config.max_open_strokes
            {
                match self.take_over(stroke, row.params, row.participant, row.n_points).await {
                    Ok(state) => {
                        next_seq = state.next_seq();
                        status = StrokeStatus::Open;
                        resent.push((stroke, state.kept().to_vec()));
                        self.strokes.insert(stroke, state);
                    }
                    Err(err) => self.fail(err),
                }
            }
            resume.push(ResumeState { stroke, next_seq, status });
        }
        (resume, resent)
    }

    /// Claims a stroke of this connection's participant (`owner`: the stroke's) that is not on
    /// this connection, and rebuilds its state from the database (its `n_points` stored
    /// samples, as last read). Marks it `open` again.
    async fn take_over(
        &mut self,
        stroke: StrokeId,
        params: penmesh::AcutsParams,
        owner: ParticipantId,
        n_points: u64,
    ) -> Result<StrokeState, ConnError> {
        if owner != self.participant {
            return Err(self.not_owner(stroke));
        }
        if !self.claims.claim(stroke, self.claim_wait()).await {
            return Err(Self::conflict(stroke));
        }
        let internal = |err: &dyn std::fmt::Display| {
            ConnError::internal(
                "resuming a stroke",
                err,
                "could not load the stroke to resume it",
                Some(stroke),
            )
        };
        let result = async {
            let store = &self.state.store;
            let state = store.replay(stroke, params, n_points).await.map_err(|e| internal(&e))?;
            self.state
                .writer
                .write(vec![WriteOp::SetStatus { stroke, status: StrokeStatus::Open }])
                .await
                .map_err(|e| internal(&e))?;
            Ok(state)
        }
        .await;
        if result.is_err() {
            self.claims.release(stroke);
        } else {
            self.own.insert(stroke);
        }
        result
    }

    /// The refusal of another participant's stroke. It says no more than the session's stroke
    /// list (`GET /v1/sessions/{id}/strokes`) tells any holder of the token.
    fn not_owner(&self, stroke: StrokeId) -> ConnError {
        ConnError::refused(
            ErrorCode::NotOwner,
            format!(
                "stroke {stroke} was begun by another participant of this session: only its \
                 drawer (the same hello.key) may resume it or append to it"
            ),
            Some(stroke),
        )
    }

    pub(super) async fn on_stroke_begin(&mut self, begin: StrokeBegin) -> Result<(), ConnError> {
        let stroke = begin.stroke;
        if let Err(err) = begin.brush.validate() {
            return Err(ConnError::refused(ErrorCode::BadBrush, err.to_string(), Some(stroke)));
        }
        let (device, max_device) = (begin.device.as_deref(), self.state.config.max_device_chars);
        if let Some(Err(why)) = device.map(|d| check_text(d, max_device)) {
            let message = format!("stroke_begin.device {why}");
            return Err(ConnError::refused(ErrorCode::Malformed, message, Some(stroke)));
        }
        let params = begin.params.unwrap_or_else(|| self.state.config.default_params());
        if let Err(err) = params.validate() {
            return Err(ConnError::refused(
                ErrorCode::BadParams,
                format!("params: {err}"),
                Some(stroke),
            ));
        }
        if let Some(state) = self.strokes.get(&stroke) {
            // A repeat on the same connection: already begun.
            let upto_seq = state.committed_seq;
            self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
            return Ok(());
        }
        if self.finishing.contains(&stroke) {
            return Err(ConnError::refused(
                ErrorCode::StrokeFinished,
                format!("stroke {stroke} has ended"),
                Some(stroke),
            ));
        }
        if self.strokes.len() >= self.state.config.max_open_strokes {
            return Err(ConnError::refused(
                ErrorCode::TooManyOpenStrokes,
                format!(
                    "this connection already has {} open strokes, the limit; end one first",
                    self.strokes.len()
                ),
                Some(stroke),
            ));
        }
        if !self.claims.claim(stroke, Duration::ZERO).await {
            // Held by another connection: refused as `not_owner` when another participant drew
            // it (waiting would not change that), else waited for as a resume is.
            if let Ok(Some(row)) = self.state.store.stroke(stroke).await
                && row.session_id == self.session
                && row.participant != self.participant
            {
                return Err(self.not_owner(stroke));
            }
            if !self.claims.claim(stroke, self.claim_wait()).await {
                return Err(Self::conflict(stroke));
            }
        }
        let existing = match self.state.store.stroke(stroke).await {
            Ok(existing) => existing,
            Err(err) => {
                self.claims.release(stroke);
                return Err(ConnError::internal(
                    "reading a stroke",
                    err,
                    "could not read the stroke",
                    Some(stroke),
                ));
            }
        };
        match existing {
            Some(row) if row.session_id != self.session => {
                self.claims.release(stroke);
                Err(ConnError::refused(
                    ErrorCode::StrokeConflict,
                    // Says no more than that the id is taken (not where, nor anything of the
                    // stroke): ids are global, see docs/reliability.md.
                    format!("stroke id {stroke} is taken; choose a new random id"),
                    Some(stroke),
                ))
            }
            Some(row) if row.participant != self.participant => {
                self.claims.release(stroke);
                Err(self.not_owner(stroke))
            }
            Some(row) if row.status == StrokeStatus::Done => {
                self.claims.release(stroke);
                self.send(ServerMessage::StrokeDone(done_message(stroke, row.n_retained)));
                Ok(())
            }
            Some(row) => {
                // Begun before on another connection: resume it.
                let state =
                    self.take_over(stroke, row.params, row.participant, row.n_points).await?;
                let kept = state.kept().to_vec();
                let upto_seq = state.committed_seq;
                self.strokes.insert(stroke, state);
                self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
                self.send_retained(stroke, 0, &kept);
                Ok(())
            }
            None => {
                let (session, participant) = (self.session, self.participant);
                let event = SessionEvent::from_connection(
                    self.id,
                    session,
                    EventKind::StrokeBegin { participant, stroke, brush: begin.brush },
                );
                let mut ops = vec![WriteOp::BeginStroke {
                    stroke,
                    session,
                    participant,
                    brush: begin.brush,
                    params,
                    device: begin.device,
                }];
                let mut events = vec![event];
                // The work plane it is drawn on (version 5): stored with its begin, and told
                // to the others right after it.
                if let Some(placement) = begin.placement {
                    let (op, event) = crate::placement::request(
                        (session, participant, stroke),
                        placement,
                        "begin",
                        Some(self.id),
                    );
                    ops.push(op);
                    events.push(event);
                }
                // What it becomes (version 6): stored with its begin, told right after it. A
                // filled stroke's closure is checked when its mesh is built.
                if let Some(solid) = begin.solid.filter(|s| !s.is_rod()) {
                    let (op, event) = crate::solid::request(
                        (session, participant, stroke),
                        solid,
                        "begin",
                        Some(self.id),
                    );
                    ops.push(op);
                    events.push(event);
                }
                let pending = self.state.writer.submit_with(ops, events).await;
                self.own.insert(stroke);
                metrics::counter!("penmesh_strokes_total", "event" => "begun").increment(1);
                self.strokes.insert(stroke, StrokeState::new(params));
                let after = AfterCommit::Ack { stroke, upto_seq: 0, retained: Decided::default() };
                self.pending.push(pending, after);
                Ok(())
            }
        }
    }

    /// Why a stroke that is not open on this connection cannot take points or an end, with
    /// its row when it is in this session.
    async fn not_open(&mut self, stroke: StrokeId) -> (ConnError, Option<StrokeRow>) {
        let finished = |row| {
            let message = format!("stroke {stroke} has ended");
            (ConnError::refused(ErrorCode::StrokeFinished, message, Some(stroke)), row)
        };
        if self.finishing.contains(&stroke) {
            return finished(None);
        }
        match self.state.store.stroke(stroke).await {
            Ok(Some(row)) if row.session_id == self.session && row.status == StrokeStatus::Done => {
                finished(Some(row))
            }
            Ok(Some(row)) if row.session_id == self.session => (
                ConnError::refused(
                    ErrorCode::UnknownStroke,
                    format!(
                        "stroke {stroke} is not open on this connection; resume it with hello.resume or stroke_begin"
                    ),
                    Some(stroke),
                ),
                Some(row),
            ),
            _ => (
                ConnError::refused(
                    ErrorCode::UnknownStroke,
                    format!("unknown stroke {stroke}: send stroke_begin first"),
                    Some(stroke),
                ),
                None,
            ),
        }
    }

    pub(super) async fn on_points(&mut self, points: Points) -> Result<(), ConnError> {
        let stroke = points.stroke;
        let limits = self.limits();
        let Some(state) = self.strokes.get_mut(&stroke) else {
            return Err(self.not_open(stroke).await.0);
        };
        self.state.counters.samples_in.increment(points.points.0.len() as u64);
        let checking = stages::start();
        let accepted = state.push_points(points.seq, &points.points.0, &limits);
        checking.stop(Stage::Acuts);
        let accepted =
            accepted.map_err(|refusal| ConnError::from_refusal(refusal, Some(stroke)))?;
        match accepted {
            Accepted::Duplicate => {
                let end = points.seq + points.points.0.len() as u64;
                if end <= state.committed_seq {
                    let upto_seq = state.committed_seq;
                    self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
                }
                // Otherwise the ack of the first copy is on its way.
            }
            Accepted::New { seq, samples, kept, first_kept } => {
                self.gather(Gathered {
                    stroke,
                    seq,
                    samples,
                    retained: Decided { first: first_kept, kept },
                })
                .await;
            }
        }
        Ok(())
    }

    /// Adds a batch to those gathered since the connection woke up, when it follows them (the
    /// same stroke, the next seq, the next retained sample) and they stay within one batch's
    /// size (`--max-batch-samples`: what a connection has in flight is bounded as before, by
    /// `--max-inflight` requests of at most that); else hands those to the writer first.
    /// Behind (its client's frames waiting in its socket), a connection reads several batches
    /// per wake-up: as one request they cost the writer, the commit's answer and the socket one
    /// round, not one each, so a connection that fell behind catches up.
    async fn gather(&mut self, batch: Gathered) {
        let most = self.state.config.max_batch_samples.max(1);
        if let Some(gathered) = &mut self.gathered
            && gathered.samples.len() + batch.samples.len() <= most
        {
            let follows_retained = batch.retained.kept.is_empty()
                || gathered.retained.kept.is_empty()
                || batch.retained.first
                    == gathered.retained.first + gathered.retained.kept.len() as u64;
            if gathered.stroke == batch.stroke
                && gathered.upto_seq() == batch.seq
                && follows_retained
            {
                gathered.samples.extend(batch.samples);
                if gathered.retained.kept.is_empty() {
                    gathered.retained.first = batch.retained.first;
                }
                gathered.retained.kept.extend(batch.retained.kept);
                return;
            }
        }
        self.hand_over_gathered().await;
        self.gathered = Some(batch);
    }

    /// Hands the gathered batches to the writer, as one request answered with one `Ack`.
    pub(super) async fn hand_over_gathered(&mut self) {
        let Some(gathered) = self.gathered.take() else { return };
        let upto_seq = gathered.upto_seq();
        let Gathered { stroke, seq, samples, retained } = gathered;
        let events =
            self.retained_event(stroke, retained.first, &retained.kept).into_iter().collect();
        let ops = vec![WriteOp::Append { stroke, seq, samples }];
        let submitting = self.state.writer.submit_with(ops, events);
        let pending = stages::timed(Stage::Submit, submitting).await;
        self.pending.push(pending, AfterCommit::Ack { stroke, upto_seq, retained });
    }

    pub(super) async fn on_stroke_end(&mut self, end: StrokeEnd) -> Result<(), ConnError> {
        let stroke = end.stroke;
        let Some(state) = self.strokes.get_mut(&stroke) else {
            let (err, row) = self.not_open(stroke).await;
            if let Some(row) =
                row.filter(|r| r.status == StrokeStatus::Done && r.n_points == end.n_points)
            {
                // A resent end after a reconnect: say done again.
                self.send(ServerMessage::StrokeDone(done_message(stroke, row.n_retained)));
                return Ok(());
            }
            return Err(err);
        };
        let Finished { last, kept } = state
            .finish(end.n_points)
            .map_err(|refusal| ConnError::from_refusal(refusal, Some(stroke)))?;
        self.strokes.remove(&stroke);
        self.finishing.insert(stroke);
        let mut events = Vec::new();
        let mut retained = Decided::default();
        if let Some((index, k)) = last {
            events.extend(self.retained_event(stroke, index, &[k]));
            retained = Decided { first: index, kept: vec![k] };
        }
        let n_retained = kept.len() as u64;
        let participant = self.participant;
        events.push(SessionEvent::from_connection(
            self.id,
            self.session,
            EventKind::StrokeDone { participant, stroke, n_retained },
        ));
        let pending =
            self.state.writer.submit_with(vec![WriteOp::Finish { stroke, kept }], events).await;
        self.pending.push(pending, AfterCommit::Done { stroke, n_retained, retained });
        Ok(())
    }

    /// The answer to a committed (or failed) write.
    pub(super) async fn after_commit(
        &mut self,
        result: Result<PlacementIds, WriteError>,
        after: AfterCommit,
    ) {
        match (result, after) {
            (Ok(placed), AfterCommit::Ack { stroke, upto_seq, retained }) => {
                // The placement its begin carried: the client holds it.
                for id in placed {
                    self.view.tell_placement(stroke, id);
                }
                if let Some(state) = self.strokes.get_mut(&stroke) {
                    state.committed_seq = state.committed_seq.max(upto_seq);
                }
                self.send_retained(stroke, retained.first, &retained.kept);
                self.send(ServerMessage::Ack(Ack { stroke, upto_seq }));
            }
            (Ok(_), AfterCommit::Done { stroke, n_retained, retained }) => {
                self.stroke_done(stroke);
                self.send_retained(stroke, retained.first, &retained.kept);
                self.send(ServerMessage::StrokeDone(done_message(stroke, n_retained)));
            }
            (Ok(_), AfterCommit::Answer { stroke, answer }) => {
                // Answered whatever the client knew: it asked.
                self.told_removed(stroke, matches!(answer, ServerMessage::StrokeRemoved(_)));
                self.send(answer)
            }
            (Ok(placed), AfterCommit::Placed { answer }) => {
                let id = placed.first().copied().unwrap_or_default();
                self.answer_placement(id, answer).await;
            }
            (Ok(_), AfterCommit::Solid { answer, row, glb }) => {
                self.answer_solid(answer, *row, glb)
            }
            (Err(err), AfterCommit::Solid { answer, .. }) => {
                self.fail(ConnError::internal(
                    "storing a stroke's solid",
                    err,
                    "storing that failed, so nothing changed; try again",
                    Some(answer.stroke),
                ));
            }
            (Err(err), AfterCommit::Placed { answer }) => {
                self.fail(ConnError::internal(
                    "storing a stroke's placement",
                    err,
                    "storing that failed, so nothing changed; try again",
                    Some(answer.stroke),
                ));
            }
            (Err(err), AfterCommit::Answer { stroke, .. }) => {
                self.fail(ConnError::internal(
                    "storing a stroke's removal",
                    err,
                    "storing that failed, so nothing changed; try again",
                    Some(stroke),
                ));
            }
            (Err(err), after) => {
                let stroke = match after {
                    AfterCommit::Ack { stroke, .. }
                    | AfterCommit::Done { stroke, .. }
                    | AfterCommit::Answer { stroke, .. } => stroke,
                    AfterCommit::Placed { answer } => answer.stroke,
                    AfterCommit::Solid { answer, .. } => answer.stroke,
                };
                // The in-memory state is ahead of the database: drop it, so the client
                // resumes from what is committed.
                self.strokes.remove(&stroke);
                self.finishing.remove(&stroke);
                self.claims.release(stroke);
                // The writer's own refusals say what is wrong, and a full disk is named; the
                // database's words stay in the log.
                let advice = match &err {
                    WriteError::Refused(why) => format!("{why}; resume it from the last ack"),
                    WriteError::Storage(_) => "storing the stroke failed: the proxy's disk is \
                                               full or failing; resume it from the last ack"
                        .to_string(),
                    _ => "storing the stroke failed; resume it from the last ack".to_string(),
                };
                self.fail(ConnError::internal("storing a stroke", err, advice, Some(stroke)));
            }
        }
    }

    /// A commit that lands after the client is gone: nobody to answer, but a finished stroke
    /// is done and let go.
    pub(super) fn after_commit_unheard(
        &mut self,
        result: Result<PlacementIds, WriteError>,
        after: AfterCommit,
    ) {
        if let (Ok(_), AfterCommit::Done { stroke, .. }) = (result, after) {
            self.stroke_done(stroke);
        }
    }

    fn stroke_done(&mut self, stroke: StrokeId) {
        self.finishing.remove(&stroke);
        self.claims.release(stroke);
        metrics::counter!("penmesh_strokes_total", "event" => "done").increment(1);
    }

    pub(super) fn send_retained(&mut self, stroke: StrokeId, first: u64, kept: &[Kept]) {
        if kept.is_empty() {
            return;
        }
        self.state.counters.samples_retained.increment(kept.len() as u64);
        let batch = self.state.config.max_batch_samples.max(1);
        for (i, chunk) in kept.chunks(batch).enumerate() {
            let points: Vec<Sample> = chunk.iter().map(|k| k.sample).collect();
            self.send(ServerMessage::Retained(Retained {
                stroke,
                first: first + (i * batch) as u64,
                points: PointBatch(points),
            }));
        }
    }

    /// The peers' event for retained samples `first..` of a stroke drawn here.
    fn retained_event(&self, stroke: StrokeId, first: u64, kept: &[Kept]) -> Option<SessionEvent> {
        if kept.is_empty() {
            return None;
        }
        let participant = self.participant;
        let points = kept.iter().map(|k| k.sample).collect();
        Some(SessionEvent::from_connection(
            self.id,
            self.session,
            EventKind::Retained { participant, stroke, first, points },
        ))
    }
}

fn done_message(stroke: StrokeId, n_retained: u64) -> StrokeDone {
    StrokeDone { stroke, n_retained, url: format!("/v1/strokes/{stroke}/simplified") }
}
