//! A stroke's raw samples as stored: its `stroke_chunks` rows and its entries in the append log,
//! read together and decoded one stored piece at a time ([`RawSamples`]).

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use anyhow::Context;
use penmesh::Sample;
use penmesh::protocol::StrokeStatus;
use sqlx::{AnyConnection, Row};
use uuid::Uuid;

use super::{Store, decode_samples, log};

impl Store {
    /// Every stored raw sample of a stroke, in order.
    pub async fn raw_samples(&self, stroke: Uuid) -> anyhow::Result<Vec<Sample>> {
        self.raw(stroke).await?.collect_all()
    }

    /// The stored raw samples of a stroke, read with one pool connection (given back before
    /// this returns) and decoded one stored piece at a time ([`RawSamples`]).
    pub async fn raw(&self, stroke: Uuid) -> anyhow::Result<RawSamples> {
        let mut conn = self.pool.acquire().await?;
        let status: Option<String> = sqlx::query_scalar("SELECT status FROM strokes WHERE id = $1")
            .bind(stroke.to_string())
            .fetch_optional(&mut *conn)
            .await?;
        // A finished stroke is all in `stroke_chunks` (moved by the commit that finished it).
        let in_log = status.is_some_and(|s| s != StrokeStatus::Done.as_str());
        let log = if in_log {
            log::read_log(&mut conn, Some(&HashSet::from([stroke])), None).await?
        } else {
            log::StrokeEntries::new()
        };
        read_raw(&mut conn, stroke, &log).await
    }

    /// The raw samples of the done strokes `strokes`, in one query (a print reads a thousand
    /// at once): a done stroke's samples are all in `stroke_chunks`, moved there by the commit
    /// that finished it. A stroke with no chunk is absent.
    pub async fn done_raw_samples_many(
        &self,
        strokes: &[Uuid],
    ) -> anyhow::Result<HashMap<Uuid, Vec<Sample>>> {
        if strokes.is_empty() {
            return Ok(HashMap::new());
        }
        let places: Vec<String> = (1..=strokes.len()).map(|i| format!("${i}")).collect();
        let sql = format!(
            "SELECT stroke_id, seq, n, layout, data FROM stroke_chunks \
             WHERE stroke_id IN ({}) ORDER BY stroke_id, seq",
            places.join(", ")
        );
        let mut query = sqlx::query(&sql);
        for stroke in strokes {
            query = query.bind(stroke.to_string());
        }
        let rows = query.fetch_all(&self.pool).await?;
        let mut chunks: HashMap<Uuid, Vec<Stored>> = HashMap::with_capacity(strokes.len());
        for row in rows {
            let stroke = super::parse_uuid(&row.try_get::<String, _>("stroke_id")?)?;
            chunks.entry(stroke).or_default().push(Stored::Chunk {
                seq: row.try_get::<i64, _>("seq")? as u64,
                n: row.try_get::<i64, _>("n")? as u64,
                layout: row.try_get("layout")?,
                data: row.try_get("data")?,
            });
        }
        chunks
            .into_iter()
            .map(|(stroke, pieces)| {
                let raw = RawSamples { stroke, pieces: pieces.into_iter(), last: None, next: 0 };
                Ok((stroke, raw.collect_all()?))
            })
            .collect()
    }

    /// A stroke's raw samples from its chunks and its entries in `log` (read by the caller).
    pub(super) async fn raw_samples_with(
        &self,
        conn: &mut AnyConnection,
        stroke: Uuid,
        log: &log::StrokeEntries,
    ) -> anyhow::Result<Vec<Sample>> {
        read_raw(conn, stroke, log).await?.collect_all()
    }
}

/// A stroke's stored samples as read: its chunk rows still encoded (a few bytes a sample),
/// and its log entries. As an iterator it gives the samples in order, one stored piece at a
/// time, decoding each piece only when it comes: the samples of a long stroke are never all
/// in memory at once. Where two pieces hold the same sample the copies must be equal, and
/// there must be no hole (as [`log::assemble`]); after an error it ends.
#[derive(Debug)]
pub struct RawSamples {
    stroke: Uuid,
    /// In `seq` order (chunks before log entries at the same seq).
    pieces: std::vec::IntoIter<Stored>,
    /// The piece that holds the last sample given (`seq`, samples), to check the copies in
    /// the pieces after it against.
    last: Option<(u64, Arc<Vec<Sample>>)>,
    /// Samples given so far.
    next: u64,
}

/// Samples `from..` of a decoded stored piece: the ones it adds to those before it.
#[derive(Debug, Clone)]
pub struct RawPiece {
    samples: Arc<Vec<Sample>>,
    from: usize,
}

impl std::ops::Deref for RawPiece {
    type Target = [Sample];
    fn deref(&self) -> &[Sample] {
        &self.samples[self.from..]
    }
}

#[derive(Debug)]
enum Stored {
    Chunk { seq: u64, n: u64, layout: i64, data: Vec<u8> },
    Log(log::Piece),
}

impl Stored {
    fn seq(&self) -> u64 {
        match self {
            Stored::Chunk { seq, .. } => *seq,
            Stored::Log(piece) => piece.seq,
        }
    }
}

impl RawSamples {
    /// Every sample, in one vector.
    pub fn collect_all(self) -> anyhow::Result<Vec<Sample>> {
        let mut samples = Vec::new();
        for piece in self {
            samples.extend_from_slice(&piece?);
        }
        Ok(samples)
    }

    fn next_piece(&mut self) -> anyhow::Result<Option<RawPiece>> {
        let stroke = self.stroke;
        for stored in self.pieces.by_ref() {
            let (seq, samples) = match stored {
                Stored::Chunk { seq, n, layout, data } => {
                    let samples = decode_samples(layout, &data)
                        .with_context(|| format!("stroke {stroke}: chunk at seq {seq}"))?;
                    anyhow::ensure!(
                        samples.len() as u64 == n,
                        "stroke {stroke}: chunk at seq {seq} has a bad length"
                    );
                    (seq, samples)
                }
                Stored::Log(piece) => (piece.seq, piece.samples),
            };
            let end = seq + samples.len() as u64;
            anyhow::ensure!(
                seq <= self.next,
                "stroke {stroke}: samples from {seq} follow {} samples",
                self.next
            );
            // The samples it holds that were given already lie in the last piece, which
            // begins at or before it (the order is by seq) and ends at `next`.
            let copies = (end.min(self.next) - seq) as usize;
            if let Some((last_seq, last)) = &self.last {
                let at = (seq - last_seq) as usize;
                anyhow::ensure!(
                    last[at..at + copies] == samples[..copies],
                    "stroke {stroke}: two stored copies of samples {seq}..{} differ",
                    seq + copies as u64
                );
            }
            if end <= self.next {
                continue;
            }
            let samples = Arc::new(samples);
            self.next = end;
            self.last = Some((seq, samples.clone()));
            return Ok(Some(RawPiece { samples, from: copies }));
        }
        Ok(None)
    }
}

/// Samples already in memory (a simplified stroke), as one piece.
impl From<Vec<Sample>> for RawSamples {
    fn from(samples: Vec<Sample>) -> RawSamples {
        let piece = Stored::Log(log::Piece { seq: 0, samples });
        RawSamples { stroke: Uuid::nil(), pieces: vec![piece].into_iter(), last: None, next: 0 }
    }
}

impl Iterator for RawSamples {
    type Item = anyhow::Result<RawPiece>;

    fn next(&mut self) -> Option<Self::Item> {
        match self.next_piece() {
            Ok(piece) => piece.map(Ok),
            Err(err) => {
                self.pieces = Vec::new().into_iter();
                Some(Err(err))
            }
        }
    }
}

/// A stroke's [`RawSamples`]: its chunk rows, and its entries in `log` (read by the caller).
async fn read_raw(
    conn: &mut AnyConnection,
    stroke: Uuid,
    log: &log::StrokeEntries,
) -> anyhow::Result<RawSamples> {
    let rows = sqlx::query(CHUNKS_SELECT).bind(stroke.to_string()).fetch_all(&mut *conn).await?;
    let mut pieces = Vec::with_capacity(rows.len());
    for row in rows {
        let seq = row.try_get::<i64, _>("seq")? as u64;
        let n = row.try_get::<i64, _>("n")? as u64;
        pieces.push(Stored::Chunk {
            seq,
            n,
            layout: row.try_get("layout")?,
            data: row.try_get("data")?,
        });
    }
    for (_, _, entry) in log.get(&stroke).into_iter().flatten() {
        pieces.push(Stored::Log(log::Piece { seq: entry.seq, samples: entry.samples.clone() }));
    }
    pieces.sort_by_key(Stored::seq); // stable: chunks before log entries at the same seq
    Ok(RawSamples { stroke, pieces: pieces.into_iter(), last: None, next: 0 })
}

/// A stroke's pieces from its `stroke_chunks` rows (`seq, n, layout, data`), decoded.
pub(crate) fn pieces_from_chunks(
    stroke: Uuid,
    rows: &[sqlx::any::AnyRow],
) -> anyhow::Result<Vec<log::Piece>> {
    let mut pieces = Vec::with_capacity(rows.len());
    for row in rows {
        let seq: i64 = row.try_get("seq")?;
        let n: i64 = row.try_get("n")?;
        let data: Vec<u8> = row.try_get("data")?;
        let layout: i64 = row.try_get("layout")?;
        let samples = decode_samples(layout, &data)
            .with_context(|| format!("stroke {stroke}: chunk at seq {seq}"))?;
        anyhow::ensure!(
            samples.len() as i64 == n,
            "stroke {stroke}: chunk at seq {seq} has a bad length"
        );
        pieces.push(log::Piece { seq: seq as u64, samples });
    }
    Ok(pieces)
}

/// Where a stroke's samples are stored, each piece as `(seq, n)` in `seq` order: its
/// `stroke_chunks` rows, and its entries in the append log. For tests that look at a database
/// directly (`fault-injection` builds only).
#[cfg(feature = "fault-injection")]
pub async fn stored_pieces(
    pool: &sqlx::AnyPool,
    stroke: Uuid,
) -> anyhow::Result<(Vec<(u64, u64)>, Vec<(u64, u64)>)> {
    let mut conn = pool.acquire().await?;
    let rows = sqlx::query("SELECT seq, n FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq")
        .bind(stroke.to_string())
        .fetch_all(&mut *conn)
        .await?;
    let mut chunks = Vec::new();
    for row in rows {
        chunks.push((row.try_get::<i64, _>("seq")? as u64, row.try_get::<i64, _>("n")? as u64));
    }
    let log = log::read_log(&mut conn, Some(&HashSet::from([stroke])), None).await?;
    let entries = log::pieces_of(&log, stroke);
    Ok((chunks, entries))
}

/// The query of a stroke's chunks that [`samples_from_chunks`] reads.
pub(crate) const CHUNKS_SELECT: &str =
    "SELECT seq, n, layout, data FROM stroke_chunks WHERE stroke_id = $1 ORDER BY seq";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::encode_samples;

    // The raw samples come piece by piece, each stored piece decoded when its turn comes:
    // copies of a sample in two pieces must agree, and a hole ends the samples with an error.
    #[test]
    fn raw_samples_come_in_order_from_overlapping_pieces() {
        let s: Vec<Sample> = (0..10).map(|i| Sample::new(i as f64, 0.0, i as f64, 0.5)).collect();
        let chunk = |seq: usize, n: usize| {
            let (layout, data) = encode_samples(&s[seq..seq + n]);
            Stored::Chunk { seq: seq as u64, n: n as u64, layout, data }
        };
        let entry = |seq: usize, n: usize| {
            Stored::Log(log::Piece { seq: seq as u64, samples: s[seq..seq + n].to_vec() })
        };
        let raw = |pieces: Vec<Stored>| RawSamples {
            stroke: Uuid::nil(),
            pieces: pieces.into_iter(),
            last: None,
            next: 0,
        };
        // Chunks [0, 6) and [2, 4) (moved twice), log entries [4, 8) and [8, 10).
        let pieces = raw(vec![chunk(0, 6), chunk(2, 2), entry(4, 4), entry(8, 2)]);
        let lengths: Vec<usize> = pieces.map(|p| p.unwrap().len()).collect();
        assert_eq!(lengths, vec![6, 2, 2], "each piece adds only what is new");
        let all = raw(vec![chunk(0, 6), chunk(2, 2), entry(4, 4), entry(8, 2)]);
        assert_eq!(all.collect_all().unwrap(), s);
        let hole = raw(vec![chunk(0, 4), entry(5, 5)]).collect_all().unwrap_err();
        assert!(hole.to_string().contains("from 5 follow 4"), "{hole}");
        let mut other = s[2..5].to_vec();
        other[1].x += 1.0;
        let differs = raw(vec![chunk(0, 4), Stored::Log(log::Piece { seq: 2, samples: other })]);
        assert!(differs.collect_all().unwrap_err().to_string().contains("differ"));
        let mut broken = raw(vec![chunk(0, 4), chunk(4, 6)]);
        if let Some(Stored::Chunk { data, .. }) = broken.pieces.as_mut_slice().get_mut(1) {
            data.truncate(2);
        }
        assert!(broken.next().unwrap().is_ok());
        assert!(broken.next().unwrap().is_err(), "a piece that cannot be decoded");
        assert!(broken.next().is_none(), "and then nothing");
    }
}
