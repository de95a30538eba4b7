//! SQUISH-E: a priority-queue simplifier bounded by the synchronised Euclidean distance (SED).
//!
//! J. Muckell, P. W. Olsen Jr., J.-H. Hwang, C. T. Lawson, S. S. Ravi, "Compression of trajectory
//! data: a comprehensive evaluation and new approach", *GeoInformatica* 18(3), 2014,
//! pp. 435–460 (SQUISH-E(λ, μ), their algorithm 1).
//!
//! Each buffered sample has a priority: an upper bound on the SED error its removal causes,
//! `π + SED(sample, predecessor, successor)`, where `π` carries the largest priority of the
//! samples already removed next to it. Samples arrive one at a time into a buffer of capacity
//! `β ≈ i / λ` (at least 4); when it is full, the sample of lowest priority is removed. At the
//! end, samples are removed while the lowest priority is `<= μ`.
//! - Ratio mode, `SquishE { ratio: λ }` with a tolerance of 0: about `n / λ` samples remain,
//!   at most `max(3, ceil(n / λ))`.
//! - Error mode, `SquishE { ratio: 1.0 }` with the tolerance `μ`: the SED of every removed sample
//!   is at most `μ`, and so is its segment distance (the synchronised point lies on the segment).
//!
//! SED here is the one of [`crate::simplification_metrics`]: the point of the segment at the
//! sample's time, or at its index fraction when both ends share one timestamp. Online as to the
//! order of decisions; the error mode buffers the whole stroke. O(n log n).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::Simplify;
use crate::model::Sample;

/// SQUISH-E(λ, μ): `ratio` is λ (`>= 1`), `run`'s tolerance is μ.
#[derive(Debug, Clone, Copy)]
pub struct SquishE {
    pub ratio: f64,
}

impl Default for SquishE {
    /// The error mode.
    fn default() -> SquishE {
        SquishE { ratio: 1.0 }
    }
}

/// The synchronised Euclidean distance of sample `i` against the segment `a–b`, `a < i < b`.
pub fn sed(samples: &[Sample], i: usize, a: usize, b: usize) -> f64 {
    let (sa, sb, si) = (&samples[a], &samples[b], &samples[i]);
    let f =
        if sb.t > sa.t { (si.t - sa.t) / (sb.t - sa.t) } else { (i - a) as f64 / (b - a) as f64 };
    si.pos().distance(sa.pos().lerp(sb.pos(), f))
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    priority: f64,
    index: usize,
    version: u32,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Entry) -> std::cmp::Ordering {
        self.priority.total_cmp(&other.priority).then(self.index.cmp(&other.index))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Entry) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// The buffer: a linked list of the samples still in it, with their priorities in a heap.
struct Buffer<'a> {
    samples: &'a [Sample],
    pred: Vec<Option<usize>>,
    succ: Vec<Option<usize>>,
    pi: Vec<f64>,
    priority: Vec<f64>,
    alive: Vec<bool>,
    version: Vec<u32>,
    heap: BinaryHeap<Reverse<Entry>>,
    len: usize,
}

impl Buffer<'_> {
    fn set_priority(&mut self, i: usize, priority: f64) {
        self.priority[i] = priority;
        self.version[i] += 1;
        self.heap.push(Reverse(Entry { priority, index: i, version: self.version[i] }));
    }

    fn adjust_priority(&mut self, i: usize) {
        if let (Some(p), Some(s)) = (self.pred[i], self.succ[i]) {
            self.set_priority(i, self.pi[i] + sed(self.samples, i, p, s));
        }
    }

    /// The live entry of lowest priority, left in the heap.
    fn peek_min(&mut self) -> Option<Entry> {
        while let Some(Reverse(entry)) = self.heap.peek().copied() {
            if self.alive[entry.index] && entry.version == self.version[entry.index] {
                return Some(entry);
            }
            self.heap.pop();
        }
        None
    }

    /// Removes the sample of lowest priority.
    fn reduce(&mut self) {
        let Some(entry) = self.peek_min() else { return };
        let j = entry.index;
        // An end (infinite priority) is never removed.
        let (Some(p), Some(s)) = (self.pred[j], self.succ[j]) else { return };
        self.heap.pop();
        self.pi[s] = self.pi[s].max(entry.priority);
        self.pi[p] = self.pi[p].max(entry.priority);
        self.succ[p] = Some(s);
        self.pred[s] = Some(p);
        self.alive[j] = false;
        self.len -= 1;
        self.adjust_priority(p);
        self.adjust_priority(s);
    }
}

impl Simplify for SquishE {
    fn name(&self) -> &'static str {
        "squish-e"
    }

    fn is_online(&self) -> bool {
        true
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        let n = samples.len();
        let ratio = if self.ratio >= 1.0 { self.ratio } else { 1.0 };
        let mut buffer = Buffer {
            samples,
            pred: vec![None; n],
            succ: vec![None; n],
            pi: vec![0.0; n],
            priority: vec![f64::INFINITY; n],
            alive: vec![false; n],
            version: vec![0; n],
            heap: BinaryHeap::with_capacity(n),
            len: 0,
        };
        let mut capacity = 4_usize;
        for i in 0..n {
            if (i + 1) as f64 / ratio >= capacity as f64 {
                capacity += 1;
            }
            buffer.alive[i] = true;
            buffer.len += 1;
            buffer.set_priority(i, f64::INFINITY);
            if i > 0 {
                buffer.succ[i - 1] = Some(i);
                buffer.pred[i] = Some(i - 1);
                buffer.adjust_priority(i - 1);
            }
            if buffer.len == capacity {
                buffer.reduce();
            }
        }
        while buffer.peek_min().is_some_and(|e| e.priority <= tolerance) {
            buffer.reduce();
        }
        (0..n).filter(|&i| buffer.alive[i]).collect()
    }
}
