//! BQS, the bounded quadrant system: an online error-bounded simplifier that decides most
//! samples in constant time.
//!
//! J. Liu, K. Zhao, P. Sommer, S. Shang, B. Kusy, R. Jurdak, "Bounded quadrant system:
//! error-bounded trajectory compression on the go", ICDE 2015, pp. 987–998.
//!
//! From the anchor `a`, the samples of the current window are summarised per quadrant around `a`
//! by their bounding box, the two bounding rays from `a` (the smallest and largest angle), and
//! the samples that define them (the *significant points*). When a sample `e` arrives:
//! - an **upper bound** on the largest distance from a window sample to the segment `a–e` is the
//!   largest distance from a vertex of (box ∩ wedge) of each quadrant: the distance to a segment
//!   is convex, so over a convex region it peaks at a vertex;
//! - a **lower bound** is the largest distance from a significant point (a real sample);
//! - if the upper bound is within the tolerance, `e` extends the window; if the lower bound is
//!   beyond it, the sample before `e` is kept and becomes the anchor; otherwise the window is
//!   scanned exactly (BQS), or the sample before `e` is kept at once (`fast`: FBQS, constant
//!   memory, the paper's fast variant).
//!
//! Distances are to the segment `a–e` (the paper uses the line through them), so every removed
//! sample lies within the tolerance of the retained segment that spans it. BQS decides exactly as
//! the plain greedy window ([`super::OpeningWindow`] without an angle).

use glam::DVec2;

use super::{Simplify, span_within, whole_if_short};
use crate::model::Sample;

/// BQS (`fast: false`, exact fallback) or FBQS (`fast: true`, conservative fallback).
#[derive(Debug, Clone, Copy, Default)]
pub struct Bqs {
    pub fast: bool,
}

/// Slack added to the bounding region so that rounding cannot shrink it below a sample.
const SLACK: f64 = 1e-9;

/// Distance from `p` to the segment from the origin to `e`.
fn distance_to_segment(p: DVec2, e: DVec2) -> f64 {
    let len2 = e.length_squared();
    if len2 == 0.0 {
        return p.length();
    }
    let t = (p.dot(e) / len2).clamp(0.0, 1.0);
    (p - e * t).length()
}

/// One quadrant's summary of the window samples in it, relative to the anchor.
#[derive(Debug, Clone, Copy)]
struct Quadrant {
    min: DVec2,
    max: DVec2,
    angle_lo: f64,
    angle_hi: f64,
    /// Samples at the box's four sides and on the two bounding rays.
    significant: [DVec2; 6],
}

impl Quadrant {
    fn new(p: DVec2, angle: f64) -> Quadrant {
        Quadrant { min: p, max: p, angle_lo: angle, angle_hi: angle, significant: [p; 6] }
    }

    fn add(&mut self, p: DVec2, angle: f64) {
        if p.x < self.min.x {
            self.min.x = p.x;
            self.significant[0] = p;
        }
        if p.x > self.max.x {
            self.max.x = p.x;
            self.significant[1] = p;
        }
        if p.y < self.min.y {
            self.min.y = p.y;
            self.significant[2] = p;
        }
        if p.y > self.max.y {
            self.max.y = p.y;
            self.significant[3] = p;
        }
        if angle < self.angle_lo {
            self.angle_lo = angle;
            self.significant[4] = p;
        }
        if angle > self.angle_hi {
            self.angle_hi = angle;
            self.significant[5] = p;
        }
    }

    /// The vertices of the box clipped to the wedge between the two bounding rays.
    fn region(&self) -> Vec<DVec2> {
        let pad = SLACK * (1.0 + self.min.abs().max_element().max(self.max.abs().max_element()));
        let (lo, hi) = (self.min - pad, self.max + pad);
        let mut polygon = vec![lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)];
        let (s, c) = (self.angle_lo - SLACK).sin_cos();
        // Left of the lower ray: cross(ray, p) >= 0.
        polygon = clip(&polygon, DVec2::new(-s, c));
        let (s, c) = (self.angle_hi + SLACK).sin_cos();
        // Right of the upper ray: cross(p, ray) >= 0.
        clip(&polygon, DVec2::new(s, -c))
    }
}

/// Clips a convex polygon to the half-plane `normal · p >= 0` (Sutherland–Hodgman).
fn clip(polygon: &[DVec2], normal: DVec2) -> Vec<DVec2> {
    let mut out = Vec::with_capacity(polygon.len() + 1);
    for (k, &p) in polygon.iter().enumerate() {
        let q = polygon[(k + 1) % polygon.len()];
        let (dp, dq) = (normal.dot(p), normal.dot(q));
        if dp >= 0.0 {
            out.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            out.push(p + (q - p) * (dp / (dp - dq)));
        }
    }
    out
}

fn quadrant_of(p: DVec2) -> usize {
    match (p.x >= 0.0, p.y >= 0.0) {
        (true, true) => 0,
        (false, true) => 1,
        (false, false) => 2,
        (true, false) => 3,
    }
}

impl Simplify for Bqs {
    fn name(&self) -> &'static str {
        if self.fast { "fbqs" } else { "bqs" }
    }

    fn is_online(&self) -> bool {
        true
    }

    fn run(&self, samples: &[Sample], tolerance: f64) -> Vec<usize> {
        if let Some(all) = whole_if_short(samples) {
            return all;
        }
        let mut kept = vec![0];
        let mut anchor = 0;
        let mut quadrants: [Option<Quadrant>; 4] = [None; 4];
        for e in 2..samples.len() {
            let origin = samples[anchor].pos();
            // `+ 0.0` turns -0.0 into 0.0, so that atan2 agrees with the quadrant.
            let p = samples[e - 1].pos() - origin + DVec2::ZERO;
            if p != DVec2::ZERO {
                let angle = p.y.atan2(p.x);
                let quadrant = &mut quadrants[quadrant_of(p)];
                match quadrant {
                    Some(q) => q.add(p, angle),
                    None => *quadrant = Some(Quadrant::new(p, angle)),
                }
            }
            let ae = samples[e].pos() - origin;
            let summaries = quadrants.iter().flatten();
            let upper = summaries
                .clone()
                .flat_map(|q| q.region())
                .map(|v| distance_to_segment(v, ae))
                .fold(0.0, f64::max);
            let admitted = upper <= tolerance || {
                let lower = summaries
                    .flat_map(|q| q.significant)
                    .map(|v| distance_to_segment(v, ae))
                    .fold(0.0, f64::max);
                lower <= tolerance && !self.fast && span_within(samples, anchor, e, tolerance)
            };
            if !admitted {
                anchor = e - 1;
                kept.push(anchor);
                quadrants = [None; 4];
            }
        }
        kept.push(samples.len() - 1);
        kept
    }
}
