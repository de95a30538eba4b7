//! Replaying strokes: from a recorded file or the stroke generator.

use std::path::Path;
use std::time::Duration;

use penmesh::{GeneratorParams, Sample, Stroke};
use tokio::sync::mpsc;
use tokio::time::Instant;

use super::{EVENT_QUEUE, PenEvent, PenEvents, PenSource};

/// Pause between two strokes of a real-time replay, in milliseconds.
pub const STROKE_GAP_MS: u64 = 250;

/// How a replay is timed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Each sample at its own timestamp, like the hand that drew it.
    Realtime,
    /// As fast as the pipeline takes them.
    Fast,
}

/// Replays whole strokes as pen events.
#[derive(Debug, Clone)]
pub struct ReplaySource {
    device: String,
    stroke_devices: Vec<String>,
    strokes: Vec<Stroke>,
    pacing: Pacing,
}

impl ReplaySource {
    /// Replays `strokes`; `device` describes where they came from.
    pub fn new(device: impl Into<String>, strokes: Vec<Stroke>, pacing: Pacing) -> ReplaySource {
        ReplaySource { device: device.into(), stroke_devices: Vec::new(), strokes, pacing }
    }

    /// Every stroke of a CSV, JSON, SVC2004 or SigComp2011 file.
    pub fn from_file(path: &Path, pacing: Pacing) -> anyhow::Result<ReplaySource> {
        let strokes = crate::io::read_strokes(path)?;
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("input");
        Ok(ReplaySource::new(format!("file:{name}"), strokes, pacing))
    }

    /// Generated strokes, one per parameter set.
    pub fn synth(params: &[GeneratorParams], pacing: Pacing) -> anyhow::Result<ReplaySource> {
        let strokes = params
            .iter()
            .map(|p| {
                penmesh::generate_stroke(p).map_err(|e| anyhow::anyhow!("bad synth setting: {e}"))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let mut source = ReplaySource::new("synth", strokes, pacing);
        source.stroke_devices = params.iter().map(|p| format!("synth:{}", p.shape)).collect();
        Ok(source)
    }

    pub fn strokes(&self) -> &[Stroke] {
        &self.strokes
    }
}

impl PenSource for ReplaySource {
    fn device(&self) -> String {
        self.device.clone()
    }

    fn stroke_devices(&self) -> Vec<String> {
        self.stroke_devices.clone()
    }

    fn total_samples(&self) -> Option<u64> {
        Some(self.strokes.iter().map(|s| s.len() as u64).sum())
    }

    fn start(self: Box<Self>) -> PenEvents {
        let (tx, rx) = mpsc::channel(EVENT_QUEUE);
        tokio::spawn(async move {
            for (stroke_idx, stroke) in self.strokes.iter().enumerate() {
                if stroke_idx > 0 && self.pacing == Pacing::Realtime {
                    tokio::time::sleep(Duration::from_millis(STROKE_GAP_MS)).await;
                }
                if !replay_stroke(stroke.samples(), self.pacing, &tx).await {
                    return;
                }
            }
        });
        rx
    }
}

/// Sends one stroke; false when the receiver is gone.
async fn replay_stroke(
    samples: &[Sample],
    pacing: Pacing,
    tx: &mpsc::Sender<anyhow::Result<PenEvent>>,
) -> bool {
    let Some(first) = samples.first() else {
        return true;
    };
    if tx.send(Ok(PenEvent::Down)).await.is_err() {
        return false;
    }
    let started = Instant::now();
    for s in samples {
        // Files may carry absolute times; a pen event's time is relative to pen-down.
        let sample = Sample { t: s.t - first.t, ..*s };
        if pacing == Pacing::Realtime {
            tokio::time::sleep_until(started + Duration::from_secs_f64(sample.t / 1e3)).await;
        }
        if tx.send(Ok(PenEvent::Sample(sample))).await.is_err() {
            return false;
        }
    }
    tx.send(Ok(PenEvent::Up)).await.is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn replays_each_stroke_between_down_and_up_with_times_from_pen_down() {
        let a =
            Stroke::new(vec![Sample::new(0.0, 0.0, 100.0, 0.5), Sample::new(1.0, 0.0, 110.0, 0.5)])
                .unwrap();
        let b = Stroke::new(vec![Sample::new(5.0, 5.0, 300.0, 0.7)]).unwrap();
        let mut rx = Box::new(ReplaySource::new("test", vec![a, b], Pacing::Fast)).start();
        let mut events = Vec::new();
        while let Some(event) = rx.recv().await {
            events.push(event.unwrap());
        }
        assert_eq!(
            events,
            vec![
                PenEvent::Down,
                PenEvent::Sample(Sample::new(0.0, 0.0, 0.0, 0.5)),
                PenEvent::Sample(Sample::new(1.0, 0.0, 10.0, 0.5)),
                PenEvent::Up,
                PenEvent::Down,
                PenEvent::Sample(Sample::new(5.0, 5.0, 0.0, 0.7)),
                PenEvent::Up,
            ]
        );
    }
}
