//! Visvalingam–Whyatt: repeatedly remove the interior sample whose triangle with its two current
//! neighbours has the smallest area.
//!
//! M. Visvalingam and J. D. Whyatt, "Line generalisation by repeated elimination of points",
//! *The Cartographic Journal* 30(1), 1993, pp. 46–51.
//!
//! Batch, O(n log n) with a heap. Three ways to stop ([`VwStop`]):
//! - [`VwStop::Area`]: when every remaining interior triangle has an area `>= threshold`
//!   (the original method; the tolerance is not used);
//! - [`VwStop::Count`]: when `count` samples remain (at least the two ends);
//! - [`VwStop::ErrorBound`]: the order is still by area, but a sample is removed only if every
//!   original sample between its neighbours then lies within the tolerance of the segment joining
//!   them; one that would break the bound is skipped until a neighbour changes. So every removed
//!   sample lies within the tolerance of its spanning segment, as with Douglas–Peucker.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::{Simplify, span_within, whole_if_short};
use crate::model::Sample;

/// When Visvalingam–Whyatt stops removing samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VwStop {
    /// Stop when the smallest triangle's area is at least this (unit²).
    Area(f64),
    /// Stop when this many samples remain.
    Count(usize),
    /// Remove only what keeps every removed sample within the tolerance of its segment.
    ErrorBound,
}

/// Visvalingam–Whyatt with a choice of stopping rule.
#[derive(Debug, Clone, Copy)]
pub struct Visvalingam {
    pub stop: VwStop,
}

impl Default for Visvalingam {
    fn default() -> Visvalingam {
        Visvalingam { stop: VwStop::ErrorBound }
    }
}

/// A heap entry: area, sample index, and the version of that sample's area when pushed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    area: f64,
    index: usize,
    version: u32,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Entry) -> std::cmp::Ordering {
        self.area.total_cmp(&other.area).then(self.index.cmp(&other.index))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Entry) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// The area of the triangle `a, b, c`.
fn triangle_area(a: &Sample, b: &Sample, c: &Sample) -> f64 {
    ((b.pos() - a.pos()).perp_dot(c.pos() - a.pos())).abs() / 2.0
}

impl Simplify for Visvalingam {
    fn name(&self) -> &'static str {
        "vw"
    }

    fn is_online(&self) -> bool {
        false
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        if let Some(all) = whole_if_short(samples) {
            return all;
        }
        let n = samples.len();
        let mut prev: Vec<usize> = (0..n).map(|i| i.saturating_sub(1)).collect();
        let mut next: Vec<usize> = (0..n).map(|i| (i + 1).min(n - 1)).collect();
        let mut alive = vec![true; n];
        let mut version = vec![0_u32; n];
        let mut heap = BinaryHeap::with_capacity(n);
        let area = |i: usize, prev: &[usize], next: &[usize]| {
            triangle_area(&samples[prev[i]], &samples[i], &samples[next[i]])
        };
        for i in 1..n - 1 {
            heap.push(Reverse(Entry { area: area(i, &prev, &next), index: i, version: 0 }));
        }
        let mut remaining = n;
        while let Some(Reverse(entry)) = heap.pop() {
            let i = entry.index;
            if !alive[i] || entry.version != version[i] {
                continue;
            }
            match self.stop {
                VwStop::Area(threshold) if entry.area >= threshold || threshold.is_nan() => break,
                VwStop::Count(count) if remaining <= count.max(2) => break,
                VwStop::ErrorBound if !span_within(samples, prev[i], next[i], tolerance) => {
                    // Skipped until a neighbour changes (which pushes a new entry).
                    continue;
                }
                _ => {}
            }
            alive[i] = false;
            remaining -= 1;
            let (p, q) = (prev[i], next[i]);
            next[p] = q;
            prev[q] = p;
            for j in [p, q] {
                if j != 0 && j != n - 1 {
                    version[j] += 1;
                    heap.push(Reverse(Entry {
                        area: area(j, &prev, &next),
                        index: j,
                        version: version[j],
                    }));
                }
            }
        }
        (0..n).filter(|&i| alive[i]).collect()
    }
}
