//! The append log (`stroke_log`, since migration `20261124000000`): each group commit writes the
//! appends it acknowledges as ONE row, a record of entries `(stroke, seq, samples)`, in a table
//! keyed only by an increasing id. So a commit dirties the end of one B-tree, not one page of a
//! per-stroke index per batch. The writer moves a stroke's samples into `stroke_chunks` (keyed,
//! compact) once, when it ends or has sat in the log for [`MOVE_AFTER`], and deletes the
//! records no stroke needs any more from the front of the log.
//!
//! A record's layout, repeated per entry: the stroke's 16 UUID bytes, LEB128 `seq`, LEB128 `n`
//! (samples), one byte `layout` (as in `stroke_chunks`), LEB128 length, the sample blob.
//! Readers of a stroke in progress read its chunks and its log entries; a sample can be in both
//! for a while (moved, its record not yet deleted): copies must be equal.

use std::collections::{HashMap, HashSet};
use std::time::Duration;

use anyhow::Context;
use penmesh::Sample;
use sqlx::{AnyConnection, Row};
use uuid::Uuid;

use super::{decode_samples, encode_samples};

/// A stroke that has had samples in the log this long is moved into `stroke_chunks` even while
/// it is being drawn: it bounds the log, hence what a reader of a stroke in progress scans.
pub(crate) const MOVE_AFTER: Duration = Duration::from_secs(2);

/// One append in a record.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Entry {
    pub stroke: Uuid,
    pub seq: u64,
    pub samples: Vec<Sample>,
}

/// A piece of a stroke as stored: a chunk row or a log entry.
#[derive(Debug, Clone)]
pub(crate) struct Piece {
    pub seq: u64,
    pub samples: Vec<Sample>,
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn get_varint(bytes: &[u8], at: &mut usize) -> anyhow::Result<u64> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let b = *bytes.get(*at).context("log record ends inside a number")?;
        *at += 1;
        v |= u64::from(b & 0x7f) << shift;
        if b < 0x80 {
            return Ok(v);
        }
    }
    anyhow::bail!("log record holds a number longer than 64 bits")
}

/// A record of `appends` (stroke, seq of its first sample, samples).
pub(crate) fn encode_record(appends: &[(Uuid, u64, &[Sample])]) -> Vec<u8> {
    let mut out = Vec::with_capacity(appends.len() * 32);
    for &(stroke, seq, samples) in appends {
        let (layout, data) = encode_samples(samples);
        out.extend_from_slice(stroke.as_bytes());
        put_varint(&mut out, seq);
        put_varint(&mut out, samples.len() as u64);
        out.push(layout as u8);
        put_varint(&mut out, data.len() as u64);
        out.extend_from_slice(&data);
    }
    out
}

/// An entry of a record, its samples not decoded yet.
struct RawEntry<'a> {
    stroke: Uuid,
    seq: u64,
    n: u64,
    layout: u8,
    data: &'a [u8],
}

impl RawEntry<'_> {
    fn decode(&self) -> anyhow::Result<Entry> {
        let (stroke, seq) = (self.stroke, self.seq);
        let samples = decode_samples(i64::from(self.layout), self.data)
            .with_context(|| format!("stroke {stroke}: log entry at seq {seq}"))?;
        anyhow::ensure!(
            samples.len() as u64 == self.n,
            "stroke {stroke}: log entry at seq {seq} has a bad length"
        );
        Ok(Entry { stroke, seq, samples })
    }
}

/// The entries of a record, their samples not decoded.
fn split_record(bytes: &[u8]) -> anyhow::Result<Vec<RawEntry<'_>>> {
    let mut entries = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let id = bytes.get(at..at + 16).context("log record ends inside a stroke id")?;
        let stroke = Uuid::from_slice(id)?;
        at += 16;
        let seq = get_varint(bytes, &mut at)?;
        let n = get_varint(bytes, &mut at)?;
        let layout = *bytes.get(at).context("log record ends before a layout")?;
        at += 1;
        let len = get_varint(bytes, &mut at)? as usize;
        let end = at.checked_add(len).context("log record holds a blob length past its end")?;
        let data = bytes.get(at..end).context("log record ends inside a sample blob")?;
        at = end;
        entries.push(RawEntry { stroke, seq, n, layout, data });
    }
    Ok(entries)
}

/// The entries of a record for the strokes `wanted` accepts (the others are skipped, not decoded).
pub(crate) fn decode_record(
    bytes: &[u8],
    wanted: impl Fn(&Uuid) -> bool,
) -> anyhow::Result<Vec<Entry>> {
    split_record(bytes)?.iter().filter(|e| wanted(&e.stroke)).map(RawEntry::decode).collect()
}

/// A stroke's log entries, each with the id and writer of its record.
pub(crate) type StrokeEntries = HashMap<Uuid, Vec<(i64, i64, Entry)>>;

/// The log entries of the strokes in `strokes` (all of them with `None`), of every writer or of
/// `writer` alone. Scans the whole log: the log holds only what is not moved yet.
pub(crate) async fn read_log(
    conn: &mut AnyConnection,
    strokes: Option<&HashSet<Uuid>>,
    writer: Option<i64>,
) -> anyhow::Result<StrokeEntries> {
    let mut out: StrokeEntries = HashMap::new();
    for (id, writer, data) in fetch_records(conn, writer).await? {
        let entries = decode_record(&data, |s| strokes.is_none_or(|set| set.contains(s)))
            .with_context(|| format!("log record {id}"))?;
        for entry in entries {
            out.entry(entry.stroke).or_default().push((id, writer, entry));
        }
    }
    Ok(out)
}

/// The log's records (id, writer, data) in order, of every writer or of `writer` alone.
async fn fetch_records(
    conn: &mut AnyConnection,
    writer: Option<i64>,
) -> anyhow::Result<Vec<(i64, i64, Vec<u8>)>> {
    let rows = match writer {
        Some(w) => {
            sqlx::query("SELECT id, writer, data FROM stroke_log WHERE writer = $1 ORDER BY id")
                .bind(w)
                .fetch_all(&mut *conn)
                .await?
        }
        None => {
            sqlx::query("SELECT id, writer, data FROM stroke_log ORDER BY id")
                .fetch_all(&mut *conn)
                .await?
        }
    };
    let mut records = Vec::with_capacity(rows.len());
    for row in rows {
        records.push((row.try_get("id")?, row.try_get("writer")?, row.try_get("data")?));
    }
    Ok(records)
}

/// Is `err` a failure of the database (or of the connection to it), rather than of what it
/// holds? The moves set aside what cannot be stored; a database failure they pass on, to be
/// tried again.
pub(crate) fn is_database_error(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| cause.is::<sqlx::Error>())
}

/// Does `stroke` have its row in `strokes`? Its samples cannot be stored without one.
pub(crate) async fn stroke_exists(conn: &mut AnyConnection, stroke: Uuid) -> anyhow::Result<bool> {
    let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM strokes WHERE id = $1")
        .bind(stroke.to_string())
        .fetch_one(&mut *conn)
        .await?;
    Ok(n > 0)
}

/// The log entries to move (of `writer` alone, or of every writer), as [`read_log`] reads
/// them, except that what does not decode is set aside ([`set_aside`]) instead of failing the
/// read: a record that does not decode at all, and every entry of a stroke one of whose
/// entries does not.
pub(crate) async fn read_log_to_move(
    conn: &mut AnyConnection,
    writer: Option<i64>,
) -> anyhow::Result<StrokeEntries> {
    let rows = fetch_records(conn, writer).await?;
    let mut out: StrokeEntries = HashMap::new();
    // Strokes with an entry that does not decode: why, and the records that hold one.
    let mut damaged: HashMap<Uuid, (String, HashSet<i64>)> = HashMap::new();
    for (id, writer, data) in rows {
        let raw = match split_record(&data) {
            Ok(raw) => raw,
            Err(err) => {
                set_aside(conn, &[id], None, &format!("log record {id}: {err:#}")).await?;
                continue;
            }
        };
        for entry in raw {
            let stroke = entry.stroke;
            match entry.decode() {
                Ok(entry) => out.entry(stroke).or_default().push((id, writer, entry)),
                Err(err) => {
                    let why = format!("log record {id}: {err:#}");
                    damaged.entry(stroke).or_insert((why, HashSet::new())).1.insert(id);
                }
            }
        }
    }
    for (stroke, (why, mut records)) in damaged {
        records.extend(out.remove(&stroke).into_iter().flatten().map(|(id, _, _)| id));
        let records: Vec<i64> = records.into_iter().collect();
        set_aside(conn, &records, Some(stroke), &why).await?;
    }
    Ok(out)
}

/// Keeps log records whose entries cannot be stored in `stroke_chunks` (of `stroke`, or the
/// whole record with `None`: it does not decode) in `stroke_log_set_aside`, for an operator:
/// a copy of each record with why. Logged and counted (`penmesh_log_set_aside_total`) once
/// per record and stroke: setting the same aside again changes nothing. The caller then
/// treats the entries as moved, so that the records can be deleted and nothing retries them.
pub(crate) async fn set_aside(
    conn: &mut AnyConnection,
    records: &[i64],
    stroke: Option<Uuid>,
    why: &str,
) -> anyhow::Result<()> {
    let stroke_id = stroke.map(|s| s.to_string()).unwrap_or_default();
    let mut added = 0;
    for &record in records {
        added += sqlx::query(
            "INSERT INTO stroke_log_set_aside (record_id, stroke_id, writer, data, reason, \
             set_aside_at) SELECT id, $1, writer, data, $2, $3 FROM stroke_log WHERE id = $4 \
             ON CONFLICT (record_id, stroke_id) DO NOTHING",
        )
        .bind(&stroke_id)
        .bind(why)
        .bind(super::now_ms())
        .bind(record)
        .execute(&mut *conn)
        .await?
        .rows_affected();
    }
    if added > 0 {
        tracing::error!(
            stroke = ?stroke, ?records, reason = why,
            "log entries that cannot be stored are set aside in stroke_log_set_aside"
        );
        metrics::counter!("penmesh_log_set_aside_total").increment(added);
    }
    Ok(())
}

/// Moves `stroke`'s log `entries` into `stroke_chunks` after its chunks (`true`: a row was
/// written), or sets them aside when they cannot be stored there: the stroke has no row, or
/// its stored samples do not decode or do not fit together. `Err` only when the database
/// fails.
pub(crate) async fn move_or_set_aside(
    conn: &mut AnyConnection,
    stroke: Uuid,
    entries: Vec<(i64, i64, Entry)>,
) -> anyhow::Result<bool> {
    let mut records: Vec<i64> = entries.iter().map(|(id, _, _)| *id).collect();
    records.dedup();
    if !stroke_exists(conn, stroke).await? {
        set_aside(conn, &records, Some(stroke), &format!("stroke {stroke} has no row")).await?;
        return Ok(false);
    }
    // The checks come before the one statement that writes: a failure here leaves the
    // transaction usable (PostgreSQL aborts it on a failed statement).
    match super::move_log_tail(conn, stroke, entries).await {
        Ok(moved) => Ok(moved),
        Err(err) if is_database_error(&err) => Err(err),
        Err(err) => {
            set_aside(conn, &records, Some(stroke), &format!("{err:#}")).await?;
            Ok(false)
        }
    }
}

/// A stroke's samples from its pieces (chunks first, then log entries, in any order): they must
/// cover `0..end` with no hole; where two pieces hold the same sample it must be the same.
pub(crate) fn assemble(stroke: Uuid, pieces: Vec<Piece>) -> anyhow::Result<Vec<Sample>> {
    assemble_from(stroke, 0, pieces)
}

/// Like [`assemble`], the samples from `start` on only (those before it are stored elsewhere).
pub(crate) fn assemble_from(
    stroke: Uuid,
    start: u64,
    mut pieces: Vec<Piece>,
) -> anyhow::Result<Vec<Sample>> {
    pieces.sort_by_key(|p| p.seq); // stable: chunks before log entries at the same seq
    let mut samples: Vec<Sample> = Vec::new();
    for piece in pieces {
        let skip = start.saturating_sub(piece.seq) as usize;
        if skip >= piece.samples.len() {
            continue;
        }
        let (seq, end) = ((piece.seq + skip as u64 - start) as usize, samples.len());
        let piece = &piece.samples[skip..];
        anyhow::ensure!(
            seq <= end,
            "stroke {stroke}: samples from {} follow {} samples",
            seq as u64 + start,
            end as u64 + start
        );
        let overlap = (end - seq).min(piece.len());
        anyhow::ensure!(
            samples[seq..seq + overlap] == piece[..overlap],
            "stroke {stroke}: two stored copies of samples {}..{} differ",
            seq as u64 + start,
            (seq + overlap) as u64 + start
        );
        samples.extend_from_slice(&piece[overlap..]);
    }
    Ok(samples)
}

/// Where `stroke`'s entries in `log` lie, each as `(seq, n)`, in `seq` order.
pub(crate) fn pieces_of(log: &StrokeEntries, stroke: Uuid) -> Vec<(u64, u64)> {
    let mut pieces: Vec<(u64, u64)> = log
        .get(&stroke)
        .into_iter()
        .flatten()
        .map(|(_, _, e)| (e.seq, e.samples.len() as u64))
        .collect();
    pieces.sort_unstable();
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_skip_other_strokes() {
        let (a, b) = (Uuid::new_v4(), Uuid::new_v4());
        let s1 = vec![Sample::new(1.0, 2.0, 3.0, 0.5), Sample::new(1.5, 2.0, 11.0, 0.5)];
        let s2 = vec![Sample::new(0.1, 0.2, 0.3, 0.4)]; // off the grid: f64 layout
        let record = encode_record(&[(a, 0, &s1), (b, 300, &s2), (a, 2, &s1)]);
        let all = decode_record(&record, |_| true).unwrap();
        assert_eq!(all.len(), 3);
        assert_eq!(all[1], Entry { stroke: b, seq: 300, samples: s2.clone() });
        let only_a = decode_record(&record, |s| *s == a).unwrap();
        assert_eq!(only_a.iter().map(|e| e.seq).collect::<Vec<_>>(), vec![0, 2]);
        assert!(decode_record(&record[..record.len() - 1], |_| true).is_err());
    }

    #[test]
    fn assembly_accepts_equal_copies_and_refuses_holes_and_different_copies() {
        let stroke = Uuid::new_v4();
        let s: Vec<Sample> = (0..6).map(|i| Sample::new(i as f64, 0.0, i as f64, 0.5)).collect();
        let piece =
            |seq: usize, n: usize| Piece { seq: seq as u64, samples: s[seq..seq + n].to_vec() };
        let whole = assemble(stroke, vec![piece(0, 4), piece(2, 2), piece(4, 2), piece(3, 3)]);
        assert_eq!(whole.unwrap(), s);
        let hole = assemble(stroke, vec![piece(0, 2), piece(3, 3)]).unwrap_err();
        assert!(hole.to_string().contains("from 3 follow 2"), "{hole}");
        let mut other = piece(2, 2);
        other.samples[0].x += 1.0;
        assert!(
            assemble(stroke, vec![piece(0, 4), other]).unwrap_err().to_string().contains("differ")
        );
        // From a start: what lies before it is skipped, what straddles it is cut.
        assert_eq!(
            assemble_from(stroke, 3, vec![piece(0, 2), piece(2, 3), piece(5, 1)]).unwrap(),
            s[3..]
        );
        assert!(assemble_from(stroke, 3, vec![piece(4, 2)]).is_err());
    }
}
