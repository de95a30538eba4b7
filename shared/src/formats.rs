//! Stroke files: readers for CSV, JSON, SVC2004 (`.TXT`) and SigComp2011 Dutch (`.hwr`), and
//! writers for CSV and JSON.
//!
//! Pure: readers take the file's text, writers return it; the caller does the file I/O.
//!
//! Every sample a reader produces is validated with the model's rules (finite values, pressure in
//! `[0, 1]`, time non-decreasing within a stroke). A bad sample is refused with
//! [`FormatError::BadSample`], which names the stroke, the sample's index in it and, where the
//! format has lines, the line. Nothing is clamped, and nothing is dropped except the hover samples
//! of `.hwr`, which that format defines as pen-up.
//!
//! # Formats
//!
//! **CSV** ([`read_csv`]): a header line naming the columns `x`, `y`, `t`, `p` in any order, plus
//! an optional `stroke` column; then one sample per line, comma separated. `t` is in ms since the
//! stroke's first sample, `p` in `[0, 1]`. Without a `stroke` column the file is one stroke. With
//! it, a new stroke starts on every line whose `stroke` value differs from the line before (the
//! value itself is only a label). Blank lines are skipped, `\r\n` line ends are accepted, and
//! unknown or repeated columns are refused.
//!
//! **JSON** ([`read_json`]): one stroke, written as `[[x, y, t, p], ...]` or
//! `{"samples": [[x, y, t, p], ...]}`, or a list of strokes (each in either form), or
//! `{"strokes": [...]}`. Other fields of an object are ignored (metadata such as an id). An empty
//! top-level list is zero strokes.
//!
//! **SVC2004** ([`read_svc2004`]): a count line `N`, then `N` lines of
//! `x y timestamp button azimuth altitude pressure`. A new stroke starts at a sample whose
//! timestamp is more than [`SVC2004_GAP_MS`] after the previous one, or whose button is 0 (the
//! SVC2004 pen-lift marks); other button values (1, and 2–5 seen in a few files) are pen-down. `t`
//! is made relative to the stroke's first sample and `p = pressure / 1023`. Coordinates stay in
//! tablet units.
//!
//! **SigComp2011 Dutch** ([`read_hwr`]): one `x y pressure` line per sample, 200 Hz, no
//! timestamps, so a sample's time is [`HWR_PERIOD_MS`] times its line index, made relative to its
//! stroke's first sample. Samples with pressure 0 are the pen hovering: they end the current stroke
//! and are not part of any stroke. `p = pressure / 1023`.

use std::fmt;

use serde::Deserialize;
use serde::de::{self, IgnoredAny, MapAccess, SeqAccess, Visitor};

use crate::model::{Sample, SampleError, Stroke};

/// Time gap (ms) above which an SVC2004 recording starts a new stroke.
pub const SVC2004_GAP_MS: f64 = 20.0;
/// Sample period (ms) of the SigComp2011 Dutch `.hwr` files (200 Hz).
pub const HWR_PERIOD_MS: f64 = 5.0;
/// Largest raw pressure level of both tablet formats; `p = level / 1023`.
pub const TABLET_PRESSURE_LEVELS: f64 = 1023.0;

/// A stroke file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StrokeFormat {
    Csv,
    Json,
    /// SVC2004 Task 2 `.TXT`.
    Svc2004,
    /// SigComp2011 Dutch `.hwr`.
    Hwr,
}

impl StrokeFormat {
    /// The format named by a file name or an extension (`"a/b.csv"`, `".json"`, `"TXT"`), by its
    /// extension, case-insensitively: `.csv`, `.json`, `.txt` (SVC2004), `.hwr`.
    pub fn from_name(name_or_extension: &str) -> Option<StrokeFormat> {
        let extension = match name_or_extension.rsplit_once('.') {
            Some((_, extension)) => extension,
            None => name_or_extension,
        };
        match extension.to_ascii_lowercase().as_str() {
            "csv" => Some(StrokeFormat::Csv),
            "json" => Some(StrokeFormat::Json),
            "txt" => Some(StrokeFormat::Svc2004),
            "hwr" => Some(StrokeFormat::Hwr),
            _ => None,
        }
    }

    /// Reads `text` in this format.
    pub fn read(self, text: &str) -> Result<Vec<Stroke>, FormatError> {
        match self {
            StrokeFormat::Csv => read_csv(text),
            StrokeFormat::Json => read_json(text),
            StrokeFormat::Svc2004 => read_svc2004(text),
            StrokeFormat::Hwr => read_hwr(text),
        }
    }
}

/// Why a stroke file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FormatError {
    /// The name or extension matches no known format.
    #[error("unknown stroke file format {hint:?}: expected .csv, .json, .txt (SVC2004) or .hwr")]
    UnknownFormat { hint: String },
    /// The text does not follow the format. Lines and columns count from 1; `column` is the
    /// 1-based field number for the line formats and the character column for JSON.
    #[error("line {line}, column {column}: {message}")]
    Syntax { line: usize, column: usize, message: String },
    /// A sample the file holds is bad input (see the data model).
    #[error("stroke {stroke}, {source}{}", line_suffix(*.line))]
    BadSample {
        /// Index of the stroke in the file's list of strokes.
        stroke: usize,
        /// The file's line that holds the sample, when the format has lines (not JSON).
        line: Option<usize>,
        /// The model's error, naming the sample's index in its stroke.
        source: SampleError,
    },
}

fn line_suffix(line: Option<usize>) -> String {
    line.map(|line| format!(" (line {line})")).unwrap_or_default()
}

fn syntax(line: usize, column: usize, message: impl Into<String>) -> FormatError {
    FormatError::Syntax { line, column, message: message.into() }
}

/// Reads strokes from `text`, choosing the format by the extension of `name_or_extension`
/// (see [`StrokeFormat::from_name`]).
pub fn read_strokes(name_or_extension: &str, text: &str) -> Result<Vec<Stroke>, FormatError> {
    StrokeFormat::from_name(name_or_extension)
        .ok_or_else(|| FormatError::UnknownFormat { hint: name_or_extension.to_string() })?
        .read(text)
}

/// Samples of one stroke as read, with the file line of each (for error messages).
#[derive(Default)]
struct StrokeBuilder {
    samples: Vec<Sample>,
    lines: Vec<Option<usize>>,
}

impl StrokeBuilder {
    fn push(&mut self, sample: Sample, line: Option<usize>) {
        self.samples.push(sample);
        self.lines.push(line);
    }

    /// Validates the stroke and appends it to `strokes`; an empty builder adds nothing.
    fn finish_into(&mut self, strokes: &mut Vec<Stroke>) -> Result<(), FormatError> {
        if self.samples.is_empty() {
            return Ok(());
        }
        let samples = std::mem::take(&mut self.samples);
        let lines = std::mem::take(&mut self.lines);
        let stroke = Stroke::new(samples).map_err(|source| FormatError::BadSample {
            stroke: strokes.len(),
            line: lines.get(source.index()).copied().flatten(),
            source,
        })?;
        strokes.push(stroke);
        Ok(())
    }
}

/// Non-blank lines of `text` with their 1-based line numbers, `\r` trimmed.
fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, line)| (i + 1, line.trim_end_matches('\r')))
        .filter(|(_, line)| !line.trim().is_empty())
}

/// Parses `n` numbers separated by whitespace (SVC2004, hwr).
fn whitespace_numbers<const N: usize>(
    line_number: usize,
    line: &str,
    what: &str,
) -> Result<[f64; N], FormatError> {
    let mut values = [0.0; N];
    let mut fields = line.split_whitespace();
    for (i, value) in values.iter_mut().enumerate() {
        let field = fields.next().ok_or_else(|| {
            syntax(line_number, i + 1, format!("expected {N} numbers ({what}), found {i}"))
        })?;
        *value = parse_number(field, line_number, i + 1)?;
    }
    if fields.next().is_some() {
        let found = N + 1 + fields.count();
        return Err(syntax(
            line_number,
            N + 1,
            format!("expected {N} numbers ({what}), found {found}"),
        ));
    }
    Ok(values)
}

fn parse_number(field: &str, line: usize, column: usize) -> Result<f64, FormatError> {
    let field = field.trim();
    field.parse::<f64>().map_err(|_| syntax(line, column, format!("{field:?} is not a number")))
}

// ---------------------------------------------------------------------------------------------
// CSV

/// Reads a CSV stroke file (see the module documentation for the format).
pub fn read_csv(text: &str) -> Result<Vec<Stroke>, FormatError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    // Each non-blank line with its number (a line of blanks only is a blank line too).
    let mut lines = reader.records().filter_map(|record| match record {
        Ok(record) if record.len() == 1 && record[0].is_empty() => None,
        Ok(record) => Some(Ok((record.position().map_or(0, |p| p.line() as usize), record))),
        Err(err) => {
            let line = err.position().map_or(0, |p| p.line() as usize);
            Some(Err(syntax(line, 1, format!("not CSV: {err}"))))
        }
    });
    let Some((header_line, header)) = lines.next().transpose()? else {
        return Err(syntax(1, 1, "empty file: expected a header line such as x,y,t,p"));
    };
    let names: Vec<&str> = header.iter().collect();
    let mut column_of = [None::<usize>; 5]; // x, y, t, p, stroke
    const NAMES: [&str; 5] = ["x", "y", "t", "p", "stroke"];
    for (column, name) in names.iter().enumerate() {
        let slot =
            NAMES.iter().position(|known| known.eq_ignore_ascii_case(name)).ok_or_else(|| {
                syntax(
                    header_line,
                    column + 1,
                    format!("unknown column {name:?}: expected x, y, t, p and optionally stroke"),
                )
            })?;
        if column_of[slot].is_some() {
            return Err(syntax(header_line, column + 1, format!("column {name:?} appears twice")));
        }
        column_of[slot] = Some(column);
    }
    for (slot, name) in NAMES.iter().enumerate().take(4) {
        if column_of[slot].is_none() {
            return Err(syntax(header_line, 1, format!("the header has no {name:?} column")));
        }
    }

    let mut strokes = Vec::new();
    let mut current = StrokeBuilder::default();
    let mut current_label: Option<String> = None;
    for line in lines {
        let (line_number, fields) = line?;
        if fields.len() != names.len() {
            return Err(syntax(
                line_number,
                fields.len().min(names.len()) + 1,
                format!("expected {} fields, found {}", names.len(), fields.len()),
            ));
        }
        let mut values = [0.0; 4];
        for (slot, value) in values.iter_mut().enumerate() {
            let column = column_of[slot].unwrap_or_default();
            *value = parse_number(&fields[column], line_number, column + 1)?;
        }
        if let Some(column) = column_of[4] {
            let label = &fields[column];
            if label.is_empty() {
                return Err(syntax(line_number, column + 1, "empty stroke label"));
            }
            if current_label.as_deref().is_some_and(|current| current != label) {
                current.finish_into(&mut strokes)?;
            }
            current_label = Some(label.to_string());
        }
        current.push(Sample::from(values), Some(line_number));
    }
    current.finish_into(&mut strokes)?;
    Ok(strokes)
}

/// Writes strokes as CSV: `x,y,t,p` for a single stroke, `stroke,x,y,t,p` (stroke = 0, 1, ...)
/// otherwise. Numbers are written in their shortest exact form, so [`read_csv`] reads back the
/// same strokes.
pub fn write_csv(strokes: &[Stroke]) -> String {
    let with_label = strokes.len() != 1;
    let mut out = String::from(if with_label { "stroke,x,y,t,p\n" } else { "x,y,t,p\n" });
    for (stroke_idx, stroke) in strokes.iter().enumerate() {
        for s in stroke.samples() {
            if with_label {
                out.push_str(&format!("{stroke_idx},"));
            }
            out.push_str(&format!("{},{},{},{}\n", s.x, s.y, s.t, s.p));
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// JSON

/// Reads a JSON stroke file (see the module documentation for the shapes accepted).
pub fn read_json(text: &str) -> Result<Vec<Stroke>, FormatError> {
    let node: JsonNode = serde_json::from_str(text)
        .map_err(|err| syntax(err.line(), err.column(), strip_position(&err.to_string())))?;
    let raw_strokes = match node {
        JsonNode::Empty => Vec::new(),
        JsonNode::Stroke(samples) => vec![samples],
        JsonNode::Strokes(strokes) => strokes,
        JsonNode::Number(_) | JsonNode::Sample(_) => {
            return Err(syntax(
                1,
                1,
                "expected a stroke ([[x, y, t, p], ...]) or a list of strokes, found a single \
                 sample or number",
            ));
        }
    };
    raw_strokes
        .into_iter()
        .enumerate()
        .map(|(stroke, samples)| {
            Stroke::new(samples).map_err(|source| FormatError::BadSample {
                stroke,
                line: None,
                source,
            })
        })
        .collect()
}

/// serde_json's message ends with " at line L column C", which [`FormatError`] says itself.
fn strip_position(message: &str) -> String {
    match message.rfind(" at line ") {
        Some(at) => message[..at].to_string(),
        None => message.to_string(),
    }
}

/// Writes strokes as a JSON list of strokes, `[[[x, y, t, p], ...], ...]`, which [`read_json`]
/// reads back.
pub fn write_json(strokes: &[Stroke]) -> String {
    // Strokes hold validated, finite samples, which always serialise.
    serde_json::to_string(strokes).expect("validated strokes serialise to JSON")
}

/// What a JSON value is, as far as strokes go. Errors raised while reading it carry serde_json's
/// line and column (of the point the parser had reached: the end of the offending value).
enum JsonNode {
    Number(f64),
    Sample(Sample),
    Stroke(Vec<Sample>),
    Strokes(Vec<Vec<Sample>>),
    /// `[]`: an empty stroke or an empty list of strokes, depending on where it is.
    Empty,
}

impl JsonNode {
    fn kind(&self) -> &'static str {
        match self {
            JsonNode::Number(_) => "a number",
            JsonNode::Sample(_) => "a sample",
            JsonNode::Stroke(_) => "a stroke",
            JsonNode::Strokes(_) => "a list of strokes",
            JsonNode::Empty => "an empty list",
        }
    }
}

impl<'de> Deserialize<'de> for JsonNode {
    fn deserialize<D: de::Deserializer<'de>>(deserializer: D) -> Result<JsonNode, D::Error> {
        deserializer.deserialize_any(JsonNodeVisitor)
    }
}

struct JsonNodeVisitor;

impl<'de> Visitor<'de> for JsonNodeVisitor {
    type Value = JsonNode;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a number, a sample [x, y, t, p], a stroke or a list of strokes")
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<JsonNode, E> {
        Ok(JsonNode::Number(v))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<JsonNode, E> {
        Ok(JsonNode::Number(v as f64))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<JsonNode, E> {
        Ok(JsonNode::Number(v as f64))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<JsonNode, A::Error> {
        let Some(first) = seq.next_element::<JsonNode>()? else {
            return Ok(JsonNode::Empty);
        };
        match first {
            JsonNode::Number(first) => {
                let mut values = vec![first];
                while let Some(node) = seq.next_element::<JsonNode>()? {
                    match node {
                        JsonNode::Number(v) => values.push(v),
                        other => return Err(mixed("numbers", other.kind())),
                    }
                }
                let values: [f64; 4] = values.as_slice().try_into().map_err(|_| {
                    de::Error::custom(format!(
                        "a sample is [x, y, t, p]: expected 4 numbers, found {}",
                        values.len()
                    ))
                })?;
                Ok(JsonNode::Sample(Sample::from(values)))
            }
            JsonNode::Sample(first) => {
                let mut samples = vec![first];
                while let Some(node) = seq.next_element::<JsonNode>()? {
                    match node {
                        JsonNode::Sample(s) => samples.push(s),
                        other => return Err(mixed("samples", other.kind())),
                    }
                }
                Ok(JsonNode::Stroke(samples))
            }
            JsonNode::Stroke(_) | JsonNode::Empty => {
                let mut strokes = vec![stroke_samples(first)];
                while let Some(node) = seq.next_element::<JsonNode>()? {
                    match node {
                        JsonNode::Stroke(_) | JsonNode::Empty => strokes.push(stroke_samples(node)),
                        other => return Err(mixed("strokes", other.kind())),
                    }
                }
                Ok(JsonNode::Strokes(strokes))
            }
            JsonNode::Strokes(_) => Err(de::Error::custom(
                "a list of lists of strokes is nested too deeply: expected a list of strokes",
            )),
        }
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<JsonNode, A::Error> {
        let mut samples: Option<JsonNode> = None;
        let mut strokes: Option<JsonNode> = None;
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "samples" | "strokes" => {
                    let slot = if key == "samples" { &mut samples } else { &mut strokes };
                    if slot.is_some() {
                        return Err(de::Error::custom(format!("field {key:?} appears twice")));
                    }
                    *slot = Some(map.next_value::<JsonNode>()?);
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        match (samples, strokes) {
            (Some(JsonNode::Stroke(samples)), None) => Ok(JsonNode::Stroke(samples)),
            (Some(JsonNode::Empty), None) => Ok(JsonNode::Stroke(Vec::new())),
            (Some(other), None) => Err(de::Error::custom(format!(
                "\"samples\" must be a list of samples [x, y, t, p], found {}",
                other.kind()
            ))),
            (None, Some(JsonNode::Strokes(strokes))) => Ok(JsonNode::Strokes(strokes)),
            (None, Some(JsonNode::Empty)) => Ok(JsonNode::Strokes(Vec::new())),
            (None, Some(other)) => Err(de::Error::custom(format!(
                "\"strokes\" must be a list of strokes, found {}",
                other.kind()
            ))),
            (Some(_), Some(_)) => {
                Err(de::Error::custom("an object has either \"samples\" or \"strokes\", not both"))
            }
            (None, None) => {
                Err(de::Error::custom("an object needs a \"samples\" or a \"strokes\" field"))
            }
        }
    }
}

fn mixed<E: de::Error>(expected: &str, found: &str) -> E {
    E::custom(format!("a list of {expected} holds {found}"))
}

fn stroke_samples(node: JsonNode) -> Vec<Sample> {
    match node {
        JsonNode::Stroke(samples) => samples,
        _ => Vec::new(),
    }
}

// ---------------------------------------------------------------------------------------------
// SVC2004

/// Reads an SVC2004 Task 2 signature file (see the module documentation).
pub fn read_svc2004(text: &str) -> Result<Vec<Stroke>, FormatError> {
    let mut lines = numbered_lines(text);
    let Some((count_line, count_text)) = lines.next() else {
        return Err(syntax(1, 1, "empty file: expected the number of points on the first line"));
    };
    let declared: usize = count_text.trim().parse().map_err(|_| {
        syntax(
            count_line,
            1,
            format!("expected the number of points, found {:?}", count_text.trim()),
        )
    })?;

    const WHAT: &str = "x y timestamp button azimuth altitude pressure";
    let mut strokes = Vec::new();
    let mut current = StrokeBuilder::default();
    let mut stroke_start_time = 0.0;
    let mut previous_time: Option<f64> = None;
    let mut n_points = 0;
    let mut last_line = count_line;
    for (line_number, line) in lines {
        let [x, y, time, button, _azimuth, _altitude, pressure] =
            whitespace_numbers::<7>(line_number, line, WHAT)?;
        n_points += 1;
        last_line = line_number;
        // A time that goes backwards never starts a stroke: it stays in the current one, where
        // validation refuses it.
        let pen_lift = previous_time
            .is_some_and(|prev| time >= prev && (button == 0.0 || time - prev > SVC2004_GAP_MS));
        if pen_lift || previous_time.is_none() {
            current.finish_into(&mut strokes)?;
            stroke_start_time = time;
        }
        previous_time = Some(time);
        let sample = Sample::new(x, y, time - stroke_start_time, pressure / TABLET_PRESSURE_LEVELS);
        current.push(sample, Some(line_number));
    }
    if n_points != declared {
        return Err(syntax(
            last_line,
            1,
            format!("the first line declares {declared} points but the file has {n_points}"),
        ));
    }
    current.finish_into(&mut strokes)?;
    Ok(strokes)
}

// ---------------------------------------------------------------------------------------------
// SigComp2011 Dutch .hwr

/// Reads a SigComp2011 Dutch `.hwr` signature file (see the module documentation).
pub fn read_hwr(text: &str) -> Result<Vec<Stroke>, FormatError> {
    let mut strokes = Vec::new();
    let mut current = StrokeBuilder::default();
    let mut stroke_start_index = 0;
    for (sample_idx, (line_number, line)) in numbered_lines(text).enumerate() {
        let [x, y, pressure] = whitespace_numbers::<3>(line_number, line, "x y pressure")?;
        if pressure == 0.0 {
            current.finish_into(&mut strokes)?;
            continue;
        }
        if current.samples.is_empty() {
            stroke_start_index = sample_idx;
        }
        let t = (sample_idx - stroke_start_index) as f64 * HWR_PERIOD_MS;
        current.push(Sample::new(x, y, t, pressure / TABLET_PRESSURE_LEVELS), Some(line_number));
    }
    current.finish_into(&mut strokes)?;
    Ok(strokes)
}
