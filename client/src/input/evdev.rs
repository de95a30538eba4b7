//! A Linux tablet through evdev (`/dev/input/event*`).
//!
//! The kernel delivers `struct input_event` records: on 64-bit Linux 24 bytes each, a
//! `timeval` (seconds and microseconds, `i64` each) then `type: u16`, `code: u16`,
//! `value: i32`, in the machine's byte order (little-endian on x86-64 and aarch64, the only
//! layout this module reads). A tablet reports `ABS_X`, `ABS_Y` and `ABS_PRESSURE` in device
//! units, `BTN_TOUCH` when the nib touches and `BTN_TOOL_PEN` while the pen is in range, and
//! closes each report with `SYN_REPORT`.
//!
//! [`EvdevDecoder`] is pure: bytes in, [`PenEvent`]s out, so it is tested on recorded event
//! sequences. Positions are scaled to pixels with the device's axis ranges: x spans
//! `canvas_width` px and y uses the same scale (tablet units are square), pressure maps to
//! `[0, 1]`. The ranges come from the `EVIOCGABS` ioctl through the `evdev` crate
//! ([`read_axis_ranges`]; the crate keeps the `unsafe` ioctl out of this workspace), or from
//! the command line, which also lets a recorded event file be replayed.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::Context;
use penmesh::Sample;
use tokio::sync::mpsc;

use super::{EVENT_QUEUE, PenEvent, PenEvents, PenSource};

/// Bytes in one `struct input_event` on 64-bit Linux.
pub const EVENT_SIZE: usize = 24;

const EV_SYN: u16 = 0x00;
const EV_KEY: u16 = 0x01;
const EV_ABS: u16 = 0x03;
const SYN_REPORT: u16 = 0;
const SYN_DROPPED: u16 = 3;
const ABS_X: u16 = 0x00;
const ABS_Y: u16 = 0x01;
const ABS_PRESSURE: u16 = 0x18;
const BTN_TOOL_PEN: u16 = 0x140;
const BTN_TOUCH: u16 = 0x14a;

/// One `struct input_event`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputEvent {
    /// Microseconds since the epoch of the event clock.
    pub time_us: i64,
    pub kind: u16,
    pub code: u16,
    pub value: i32,
}

/// Decodes whole records; a trailing partial record is an error.
pub fn decode_events(bytes: &[u8]) -> anyhow::Result<Vec<InputEvent>> {
    anyhow::ensure!(
        bytes.len() % EVENT_SIZE == 0,
        "{} bytes is not a whole number of {EVENT_SIZE}-byte input events",
        bytes.len()
    );
    Ok(bytes.chunks_exact(EVENT_SIZE).map(decode_event).collect())
}

fn decode_event(record: &[u8]) -> InputEvent {
    let i64_at = |at: usize| i64::from_le_bytes(record[at..at + 8].try_into().unwrap());
    let u16_at = |at: usize| u16::from_le_bytes(record[at..at + 2].try_into().unwrap());
    InputEvent {
        time_us: i64_at(0).saturating_mul(1_000_000).saturating_add(i64_at(8)),
        kind: u16_at(16),
        code: u16_at(18),
        value: i32::from_le_bytes(record[20..24].try_into().unwrap()),
    }
}

/// Encodes one record as the kernel writes it (for recording fixtures and tests).
pub fn encode_event(event: &InputEvent) -> [u8; EVENT_SIZE] {
    let mut record = [0u8; EVENT_SIZE];
    record[0..8].copy_from_slice(&event.time_us.div_euclid(1_000_000).to_le_bytes());
    record[8..16].copy_from_slice(&event.time_us.rem_euclid(1_000_000).to_le_bytes());
    record[16..18].copy_from_slice(&event.kind.to_le_bytes());
    record[18..20].copy_from_slice(&event.code.to_le_bytes());
    record[20..24].copy_from_slice(&event.value.to_le_bytes());
    record
}

/// The range of one absolute axis, in device units.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisRange {
    pub min: i32,
    pub max: i32,
}

impl AxisRange {
    /// Parses `MIN:MAX`.
    pub fn parse(text: &str) -> Result<AxisRange, String> {
        let (min, max) = text.split_once(':').ok_or_else(|| format!("{text:?} is not MIN:MAX"))?;
        let parse = |v: &str| v.trim().parse::<i32>().map_err(|e| format!("{v:?}: {e}"));
        let range = AxisRange { min: parse(min)?, max: parse(max)? };
        if range.max <= range.min {
            return Err(format!("{text:?}: MAX must be larger than MIN"));
        }
        Ok(range)
    }

    fn span(&self) -> f64 {
        f64::from(self.max) - f64::from(self.min)
    }
}

/// The axis ranges that scale a device's reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisRanges {
    pub x: AxisRange,
    pub y: AxisRange,
    /// `None` for a device without pressure: every touching sample has pressure 1.
    pub pressure: Option<AxisRange>,
    /// Pixels spanned by the x range; y uses the same scale.
    pub canvas_width: f64,
}

impl AxisRanges {
    fn scale(&self) -> f64 {
        self.canvas_width / self.x.span().max(1.0)
    }
}

/// Turns input events into pen events: pure, one event at a time.
#[derive(Debug, Clone)]
pub struct EvdevDecoder {
    ranges: AxisRanges,
    x: i32,
    y: i32,
    pressure: i32,
    touch: bool,
    seen_touch_key: bool,
    in_range: bool,
    down: bool,
    down_at_us: i64,
    last_t: f64,
    /// After `SYN_DROPPED`, events are discarded up to the next `SYN_REPORT`.
    dropping: bool,
}

impl EvdevDecoder {
    pub fn new(ranges: AxisRanges) -> EvdevDecoder {
        EvdevDecoder {
            ranges,
            x: ranges.x.min,
            y: ranges.y.min,
            pressure: ranges.pressure.map_or(0, |p| p.min),
            touch: false,
            seen_touch_key: false,
            in_range: true,
            down: false,
            down_at_us: 0,
            last_t: 0.0,
            dropping: false,
        }
    }

    /// Feeds one event; pen events are appended to `out` at each `SYN_REPORT`.
    pub fn push(&mut self, event: &InputEvent, out: &mut Vec<PenEvent>) {
        if self.dropping {
            if event.kind == EV_SYN && event.code == SYN_REPORT {
                self.dropping = false;
            }
            return;
        }
        match (event.kind, event.code) {
            (EV_ABS, ABS_X) => self.x = event.value,
            (EV_ABS, ABS_Y) => self.y = event.value,
            (EV_ABS, ABS_PRESSURE) => self.pressure = event.value,
            (EV_KEY, BTN_TOUCH) => {
                self.seen_touch_key = true;
                self.touch = event.value != 0;
            }
            (EV_KEY, BTN_TOOL_PEN) => self.in_range = event.value != 0,
            (EV_SYN, SYN_DROPPED) => self.dropping = true,
            (EV_SYN, SYN_REPORT) => self.report(event.time_us, out),
            _ => {}
        }
    }

    /// Ends the input: a stroke still down is closed.
    pub fn finish(&mut self, out: &mut Vec<PenEvent>) {
        if self.down {
            self.down = false;
            out.push(PenEvent::Up);
        }
    }

    fn touching(&self) -> bool {
        let touching = if self.seen_touch_key {
            self.touch
        } else {
            // A device without BTN_TOUCH: pressure above its minimum means contact.
            self.ranges.pressure.is_some_and(|p| self.pressure > p.min)
        };
        touching && self.in_range
    }

    fn report(&mut self, time_us: i64, out: &mut Vec<PenEvent>) {
        let touching = self.touching();
        if touching && !self.down {
            self.down = true;
            self.down_at_us = time_us;
            self.last_t = 0.0;
            out.push(PenEvent::Down);
        } else if !touching && self.down {
            self.down = false;
            out.push(PenEvent::Up);
            return;
        }
        if !self.down {
            return;
        }
        // Event clocks can step back (a clock change); keep time non-decreasing.
        let t = ((time_us - self.down_at_us) as f64 / 1e3).max(self.last_t);
        self.last_t = t;
        let scale = self.ranges.scale();
        let p = match self.ranges.pressure {
            Some(range) => {
                ((f64::from(self.pressure) - f64::from(range.min)) / range.span()).clamp(0.0, 1.0)
            }
            None => 1.0,
        };
        out.push(PenEvent::Sample(Sample::new(
            (f64::from(self.x) - f64::from(self.ranges.x.min)) * scale,
            (f64::from(self.y) - f64::from(self.ranges.y.min)) * scale,
            t,
            p,
        )));
    }
}

/// Reads `ABS_X`, `ABS_Y` and `ABS_PRESSURE` ranges and the name of an evdev device.
#[cfg(target_os = "linux")]
pub fn read_axis_ranges(
    path: &Path,
) -> anyhow::Result<(String, AxisRange, AxisRange, Option<AxisRange>)> {
    use evdev::AbsoluteAxisCode;
    let device = evdev::Device::open(path)
        .with_context(|| format!("{}: cannot open as an evdev device", path.display()))?;
    let name = device.name().unwrap_or("evdev device").to_string();
    let (mut x, mut y, mut pressure) = (None, None, None);
    let infos = device
        .get_absinfo()
        .with_context(|| format!("{}: cannot read the axis ranges (EVIOCGABS)", path.display()))?;
    for (axis, info) in infos {
        let range = AxisRange { min: info.minimum(), max: info.maximum() };
        if range.max <= range.min {
            continue;
        }
        match axis {
            AbsoluteAxisCode::ABS_X => x = Some(range),
            AbsoluteAxisCode::ABS_Y => y = Some(range),
            AbsoluteAxisCode::ABS_PRESSURE => pressure = Some(range),
            _ => {}
        }
    }
    let missing = |axis: &str| anyhow::anyhow!("{}: {name} has no {axis} axis", path.display());
    Ok((
        name.clone(),
        x.ok_or_else(|| missing("ABS_X"))?,
        y.ok_or_else(|| missing("ABS_Y"))?,
        pressure,
    ))
}

/// Without evdev, ranges must be given on the command line.
#[cfg(not(target_os = "linux"))]
pub fn read_axis_ranges(
    path: &Path,
) -> anyhow::Result<(String, AxisRange, AxisRange, Option<AxisRange>)> {
    anyhow::bail!(
        "{}: reading a device's axis ranges needs Linux; pass --abs-x and --abs-y",
        path.display()
    )
}

/// A tablet (or a recorded event file) read through evdev.
#[derive(Debug, Clone)]
pub struct EvdevSource {
    path: PathBuf,
    name: String,
    ranges: AxisRanges,
}

impl EvdevSource {
    pub fn new(path: PathBuf, name: String, ranges: AxisRanges) -> EvdevSource {
        EvdevSource { path, name, ranges }
    }
}

impl PenSource for EvdevSource {
    fn device(&self) -> String {
        format!("evdev:{}", self.name)
    }

    fn total_samples(&self) -> Option<u64> {
        None
    }

    fn start(self: Box<Self>) -> PenEvents {
        let (tx, rx) = mpsc::channel(EVENT_QUEUE);
        // Reading a character device blocks: a thread of its own.
        tokio::task::spawn_blocking(move || {
            if let Err(err) = read_device(&self.path, self.ranges, &tx) {
                let _ = tx.blocking_send(Err(err));
            }
        });
        rx
    }
}

fn read_device(
    path: &Path,
    ranges: AxisRanges,
    tx: &mpsc::Sender<anyhow::Result<PenEvent>>,
) -> anyhow::Result<()> {
    let mut file = fs_err::File::open(path)?;
    let mut decoder = EvdevDecoder::new(ranges);
    let mut record = [0u8; EVENT_SIZE];
    let mut out = Vec::new();
    loop {
        match file.read_exact(&mut record) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::UnexpectedEof => break,
            Err(err) => return Err(err).with_context(|| format!("reading {}", path.display())),
        }
        decoder.push(&decode_event(&record), &mut out);
        for event in out.drain(..) {
            if tx.blocking_send(Ok(event)).is_err() {
                return Ok(());
            }
        }
    }
    decoder.finish(&mut out);
    for event in out {
        let _ = tx.blocking_send(Ok(event));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ranges() -> AxisRanges {
        AxisRanges {
            x: AxisRange { min: 0, max: 1000 },
            y: AxisRange { min: 0, max: 500 },
            pressure: Some(AxisRange { min: 0, max: 1023 }),
            canvas_width: 100.0,
        }
    }

    fn ev(time_us: i64, kind: u16, code: u16, value: i32) -> InputEvent {
        InputEvent { time_us, kind, code, value }
    }

    fn decode(events: &[InputEvent]) -> Vec<PenEvent> {
        let mut decoder = EvdevDecoder::new(ranges());
        let mut out = Vec::new();
        for e in events {
            decoder.push(e, &mut out);
        }
        decoder.finish(&mut out);
        out
    }

    #[test]
    fn records_round_trip_through_bytes() {
        let e = ev(1_700_000_000_123_456, EV_ABS, ABS_PRESSURE, -5);
        assert_eq!(decode_events(&encode_event(&e)).unwrap(), vec![e]);
        assert!(decode_events(&[0u8; 25]).is_err());
    }

    #[test]
    fn touch_scales_position_and_pressure_and_times_from_pen_down() {
        let out = decode(&[
            ev(1_000_000, EV_KEY, BTN_TOOL_PEN, 1),
            ev(1_000_000, EV_ABS, ABS_X, 500),
            ev(1_000_000, EV_ABS, ABS_Y, 250),
            ev(1_000_000, EV_SYN, SYN_REPORT, 0),
            ev(1_010_000, EV_KEY, BTN_TOUCH, 1),
            ev(1_010_000, EV_ABS, ABS_PRESSURE, 1023),
            ev(1_010_000, EV_SYN, SYN_REPORT, 0),
            ev(1_015_000, EV_ABS, ABS_X, 600),
            ev(1_015_000, EV_SYN, SYN_REPORT, 0),
            ev(1_020_000, EV_KEY, BTN_TOUCH, 0),
            ev(1_020_000, EV_SYN, SYN_REPORT, 0),
        ]);
        assert_eq!(
            out,
            vec![
                PenEvent::Down,
                PenEvent::Sample(Sample::new(50.0, 25.0, 0.0, 1.0)),
                PenEvent::Sample(Sample::new(60.0, 25.0, 5.0, 1.0)),
                PenEvent::Up,
            ]
        );
    }

    #[test]
    fn leaving_range_lifts_the_pen_and_the_end_closes_an_open_stroke() {
        let out = decode(&[
            ev(0, EV_KEY, BTN_TOUCH, 1),
            ev(0, EV_SYN, SYN_REPORT, 0),
            ev(1000, EV_KEY, BTN_TOOL_PEN, 0),
            ev(1000, EV_SYN, SYN_REPORT, 0),
            ev(2000, EV_KEY, BTN_TOOL_PEN, 1),
            ev(2000, EV_SYN, SYN_REPORT, 0),
        ]);
        assert_eq!(out.iter().filter(|e| **e == PenEvent::Down).count(), 2);
        assert_eq!(out.last(), Some(&PenEvent::Up));
    }

    #[test]
    fn a_dropped_report_is_skipped_up_to_the_next_report() {
        let out = decode(&[
            ev(0, EV_KEY, BTN_TOUCH, 1),
            ev(0, EV_SYN, SYN_REPORT, 0),
            ev(1000, EV_SYN, SYN_DROPPED, 0),
            ev(1000, EV_ABS, ABS_X, 999),
            ev(1000, EV_SYN, SYN_REPORT, 0),
            ev(2000, EV_ABS, ABS_Y, 100),
            ev(2000, EV_SYN, SYN_REPORT, 0),
        ]);
        let xs: Vec<f64> = out
            .iter()
            .filter_map(|e| if let PenEvent::Sample(s) = e { Some(s.x) } else { None })
            .collect();
        assert_eq!(xs, vec![0.0, 0.0]);
    }

    #[test]
    fn without_a_touch_key_pressure_means_contact() {
        let out = decode(&[
            ev(0, EV_ABS, ABS_PRESSURE, 10),
            ev(0, EV_SYN, SYN_REPORT, 0),
            ev(1000, EV_ABS, ABS_PRESSURE, 0),
            ev(1000, EV_SYN, SYN_REPORT, 0),
        ]);
        assert_eq!(out.len(), 3);
        assert_eq!(out[0], PenEvent::Down);
        assert_eq!(out[2], PenEvent::Up);
    }

    #[test]
    fn axis_ranges_parse_from_the_command_line() {
        assert_eq!(AxisRange::parse("0:21600"), Ok(AxisRange { min: 0, max: 21600 }));
        assert!(AxisRange::parse("5:5").is_err());
        assert!(AxisRange::parse("x").is_err());
    }
}
