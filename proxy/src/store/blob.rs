//! The layout of sample and index blobs in the database (a row's `layout` column): the codec's
//! compact point batch, or `f64` quadruples for rows of earlier versions.

use penmesh::Sample;
use penmesh::protocol::{decode_point_batch, encode_point_batch, quantize_sample};

/// How a row's sample blob is laid out (its `layout` column).
const LAYOUT_F64: i64 = 0;

/// [`penmesh::protocol::encode_point_batch`]: exact for samples on the codec's grid, which is
/// every sample the proxy accepts since it puts them there on arrival (`ingest`).
const LAYOUT_POINT_BATCH: i64 = 1;

/// A sample blob and its layout: the compact point batch when that is exact (every sample on
/// the grid, bit for bit), else `f64` quadruples (samples stored by an earlier version).
pub(crate) fn encode_samples(samples: &[Sample]) -> (i64, Vec<u8>) {
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
    let on_grid = samples.iter().all(|s| {
        let q = quantize_sample(s);
        same(q.x, s.x) && same(q.y, s.y) && same(q.t, s.t) && same(q.p, s.p)
    });
    if on_grid {
        return (LAYOUT_POINT_BATCH, encode_point_batch(samples));
    }
    let mut out = Vec::with_capacity(samples.len() * 32);
    for s in samples {
        for v in [s.x, s.y, s.t, s.p] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    (LAYOUT_F64, out)
}

/// The samples of a stored blob of the given `layout` (a row's `layout` column). Public for
/// tests that read a database file directly.
pub fn decode_samples(layout: i64, bytes: &[u8]) -> anyhow::Result<Vec<Sample>> {
    match layout {
        LAYOUT_POINT_BATCH => Ok(decode_point_batch(bytes)?),
        LAYOUT_F64 => {
            anyhow::ensure!(
                bytes.len() % 32 == 0,
                "sample blob of {} bytes is not a multiple of 32",
                bytes.len()
            );
            Ok(bytes
                .chunks_exact(32)
                .map(|c| {
                    let f = |i: usize| f64::from_le_bytes(c[i * 8..i * 8 + 8].try_into().unwrap());
                    Sample::new(f(0), f(1), f(2), f(3))
                })
                .collect())
        }
        other => anyhow::bail!("unknown sample layout {other}"),
    }
}

pub(crate) fn encode_indices(indices: &[u64]) -> Vec<u8> {
    indices.iter().flat_map(|i| i.to_le_bytes()).collect()
}

pub(super) fn decode_indices(bytes: &[u8]) -> Vec<u64> {
    bytes.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_round_trip_through_the_blob() {
        // On the grid: the compact layout, at a few bytes a sample.
        let samples = vec![Sample::new(1.5, -2.0, 3.25, 0.5), Sample::new(0.0, 0.0, 4.0, 1.0)];
        let (layout, bytes) = encode_samples(&samples);
        assert_eq!(layout, LAYOUT_POINT_BATCH);
        assert!(bytes.len() < 16, "{} bytes, not a quarter of the f64 form", bytes.len());
        assert_eq!(decode_samples(layout, &bytes).unwrap(), samples);
        // Off it (stored by an earlier version): f64, exact.
        let old = vec![Sample::new(0.1, 0.2, 0.3, 0.4)];
        let (layout, bytes) = encode_samples(&old);
        assert_eq!(layout, LAYOUT_F64);
        assert_eq!(decode_samples(layout, &bytes).unwrap(), old);
        assert!(decode_samples(LAYOUT_F64, &[0; 31]).is_err());
        assert!(decode_samples(LAYOUT_POINT_BATCH, &[]).is_err());
        assert!(decode_samples(7, &bytes).unwrap_err().to_string().contains("layout 7"));
    }
}
