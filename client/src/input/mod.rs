//! Input sources: where pen events come from.
//!
//! Every source turns into one stream of [`PenEvent`]s (pen down, raw samples, pen up) through
//! the [`PenSource`] trait, so the live path (resample, batch, stream) does not know whether a
//! person, a file or the generator is drawing.
//!
//! - [`ReplaySource`]: strokes of a recorded file, or generated ones, replayed at their own
//!   timestamps ([`Pacing::Realtime`]) or as fast as the pipeline takes them ([`Pacing::Fast`]).
//! - [`EvdevSource`]: a Linux tablet through `/dev/input/event*`, decoded by the pure
//!   [`EvdevDecoder`].

mod evdev;
mod replay;

use penmesh::Sample;
use tokio::sync::mpsc;

pub use self::evdev::{
    AxisRange, AxisRanges, EVENT_SIZE, EvdevDecoder, EvdevSource, InputEvent, decode_events,
    encode_event, read_axis_ranges,
};
pub use self::replay::{Pacing, ReplaySource, STROKE_GAP_MS};

/// One thing the pen did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PenEvent {
    /// The pen touched: a stroke begins.
    Down,
    /// A raw sample of the stroke being drawn; `t` is milliseconds since [`PenEvent::Down`].
    Sample(Sample),
    /// The pen lifted: the stroke ends.
    Up,
}

/// Events as they come; an `Err` ends the stream.
pub type PenEvents = mpsc::Receiver<anyhow::Result<PenEvent>>;

/// Capacity of the channel a source fills: a fast replay waits for the pipeline beyond it.
pub const EVENT_QUEUE: usize = 1024;

/// Something a person (or a file, or the generator) draws with.
pub trait PenSource: Send {
    /// Describes the device for `StrokeBegin.device`, e.g. `synth:figure8` or `file:a.csv`.
    fn device(&self) -> String;

    /// The device of each stroke, when the source knows them in advance and they differ
    /// (e.g. `synth:figure8` then `synth:leaf`); [`PenSource::device`] for the rest.
    fn stroke_devices(&self) -> Vec<String> {
        Vec::new()
    }

    /// How many samples will be drawn, when known in advance (for a progress bar).
    fn total_samples(&self) -> Option<u64>;

    /// Starts producing events on a task of the current runtime.
    fn start(self: Box<Self>) -> PenEvents;
}
