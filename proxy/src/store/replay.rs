//! Rebuilding a stroke's ACUTS state from its stored samples (a resume, a session's history),
//! with long strokes held to `--max-replays` at once.

use anyhow::Context;
use uuid::Uuid;

use super::Store;

/// Stored samples of an unfinished stroke from which replaying it (to rebuild what ACUTS
/// retained: a session's history, a resume) counts as long: it waits for one of
/// `--max-replays` permits and runs on the blocking pool, and a history keeps what it retains
/// ([`WriteOp::KeepRetained`](super::WriteOp::KeepRetained)). A shorter one is replayed on the spot (at most a few
/// milliseconds; see docs/reliability.md).
pub const LONG_STROKE_SAMPLES: u64 = 2048;

impl Store {
    /// Replays the stored samples of `stroke` (`n_points` of them, as far as the caller
    /// knows) through a fresh simplifier ([`crate::ingest::StrokeState::replay`]). A long
    /// stroke ([`LONG_STROKE_SAMPLES`]) first waits for one of `--max-replays` permits, before
    /// it takes a pool connection, and is replayed on the blocking pool: however many ask, the
    /// replica replays that many long strokes at once, holding that many of them in memory.
    pub async fn replay(
        &self,
        stroke: Uuid,
        params: penmesh::AcutsParams,
        n_points: u64,
    ) -> anyhow::Result<crate::ingest::StrokeState> {
        use crate::ingest::StrokeState;
        if n_points < LONG_STROKE_SAMPLES {
            let samples = self.raw_samples(stroke).await?;
            return Ok(StrokeState::replay(params, &samples));
        }
        let _permit = self.replays.acquire().await.context("the replay permits are closed")?;
        let samples = self.raw_samples(stroke).await?;
        metrics::counter!("penmesh_replayed_samples_total").increment(samples.len() as u64);
        tokio::task::spawn_blocking(move || StrokeState::replay(params, &samples))
            .await
            .context("replaying a stroke")
    }
}
