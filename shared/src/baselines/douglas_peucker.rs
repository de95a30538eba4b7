//! Douglas–Peucker: keep the ends, then recursively keep the sample farthest from the segment
//! joining the current ends while it lies beyond the tolerance.
//!
//! D. H. Douglas and T. K. Peucker, "Algorithms for the reduction of the number of points
//! required to represent a digitized line or its caricature", *The Canadian Cartographer* 10(2),
//! 1973, pp. 112–122.
//!
//! Batch: it needs the whole stroke. Distances are to the segment (not the infinite line), so
//! every removed sample lies within the tolerance of the retained segment that spans it.
//! O(n log n) typical, O(n²) worst case.

use super::{Simplify, whole_if_short};
use crate::acuts::segment_distance;
use crate::model::Sample;

/// Douglas–Peucker with segment distances.
#[derive(Debug, Clone, Copy, Default)]
pub struct DouglasPeucker;

impl Simplify for DouglasPeucker {
    fn name(&self) -> &'static str {
        "dp"
    }

    fn is_online(&self) -> bool {
        false
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        if let Some(all) = whole_if_short(samples) {
            return all;
        }
        let n = samples.len();
        let mut keep = vec![false; n];
        keep[0] = true;
        keep[n - 1] = true;
        let mut spans = vec![(0, n - 1)];
        while let Some((a, b)) = spans.pop() {
            let (sa, sb) = (&samples[a], &samples[b]);
            let farthest = (a + 1..b)
                .map(|k| (k, segment_distance(&samples[k], sa, sb)))
                .max_by(|x, y| x.1.total_cmp(&y.1));
            if let Some((k, distance)) = farthest
                && distance > tolerance
            {
                keep[k] = true;
                spans.push((a, k));
                spans.push((k, b));
            }
        }
        (0..n).filter(|&i| keep[i]).collect()
    }
}
