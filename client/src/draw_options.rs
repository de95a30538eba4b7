//! How one person draws: the settings of the live path and of the reconstruction after each
//! stroke, with their defaults.

use std::path::PathBuf;
use std::time::Duration;

use indicatif::ProgressBar;
use penmesh::{Brush, GlbEncoding, Placement};

/// Default time between two batches, ms.
pub const DEFAULT_BATCH_MS: u64 = 16;
/// Default largest batch, samples.
pub const DEFAULT_BATCH_SAMPLES: usize = 64;
/// Default time to keep trying to reach the proxy again after a lost connection, s.
pub const DEFAULT_RETRY_SECS: u64 = 30;
/// How one person draws.
#[derive(Debug, Clone)]
pub struct DrawOptions {
    /// Display name, also the GLB author and file name prefix.
    pub name: String,
    /// The participant key (`Hello.key`, and `x-penmesh-key` of the mesh upload): made once,
    /// so that a reconnect resumes this person's strokes and only this person may.
    pub key: String,
    pub brush: Brush,
    /// The work plane each stroke is drawn on (`StrokeBegin.placement`); `None`: the board.
    pub placement: Option<Placement>,
    /// What each stroke becomes once done (`PUT /v1/strokes/{id}/solid` when not the rod), and
    /// the solid its mesh is built as.
    pub solid: penmesh::Solid,
    /// Stage-1 resampling distance `l_eps`.
    pub resample: f64,
    /// Stage 1's repeat rule (`penmesh::Resampler::drop_repeats`): exact repeats of the last
    /// sample sent are not sent; `false` streams them too.
    pub drop_repeats: bool,
    /// Send what was kept at least this often.
    pub batch_interval: Duration,
    /// Send as soon as this many kept samples wait.
    pub batch_samples: usize,
    /// After a lost connection, keep trying this long without progress.
    pub retry_for: Duration,
    /// How each stroke's GLB is written (and uploaded).
    pub glb: GlbEncoding,
    /// Where to write each stroke's GLB.
    pub out_dir: Option<PathBuf>,
    /// Advanced by one per drawn sample.
    pub progress: Option<ProgressBar>,
    /// Counts interrupts (Ctrl-C): the first ends the input as if the source ended, so what
    /// was drawn is still stored and meshed; the second gives up at once.
    pub interrupts: Option<tokio::sync::watch::Receiver<u32>>,
}

impl DrawOptions {
    /// A stroke's stage 1, as these options set it.
    pub fn resampler(&self) -> penmesh::Resampler {
        penmesh::Resampler::new(self.resample).drop_repeats(self.drop_repeats)
    }

    pub fn new(name: impl Into<String>) -> DrawOptions {
        DrawOptions {
            name: name.into(),
            key: crate::wire::new_participant_key(),
            brush: Brush::default(),
            placement: None,
            solid: penmesh::Solid::ROD,
            resample: penmesh::DEFAULT_RESAMPLE_DISTANCE,
            drop_repeats: true,
            batch_interval: Duration::from_millis(DEFAULT_BATCH_MS),
            batch_samples: DEFAULT_BATCH_SAMPLES,
            retry_for: Duration::from_secs(DEFAULT_RETRY_SECS),
            glb: GlbEncoding::default(),
            out_dir: None,
            progress: None,
            interrupts: None,
        }
    }
}
