//! A deterministic stroke generator: strokes like a person draws them on a pen tablet, for demos,
//! tests and benchmarks when no recording is at hand.
//!
//! Shapes: the paper's four classic contours (figure-8, multiple semicircles, chromosome, leaf;
//! section IV) and handwriting-like scribbles (cursive loops of varying height). What makes them
//! look drawn rather than plotted:
//! - **Speed** follows the two-thirds power law of human movement, `v ∝ κ^(-1/3)` (curvature `κ`
//!   clamped to radii between 1 % and 100 % of the shape's size), so the pen slows in curves and
//!   corners, and it accelerates from and decelerates to rest over the first and last 6 % of the
//!   path. The average speed (path length over duration, dwell included) is the requested one.
//! - **Dwell**: a few samples nearly still at pen-down (3–5) and at pen-up (2–4).
//! - **Jitter**: hand tremor as correlated noise (AR(1), `rho = 0.85`, 0.35 px standard
//!   deviation per axis), and a small seeded rotation (±4°) and stretch (±5 %) of the shape.
//! - **Pressure** ramps up at pen-down, varies slowly (more on the semicircles and the leaf, as in
//!   the paper's figure 13), drops a little where the pen is fast, and tapers at pen-up. It stays
//!   in `[0.01, 1]`.
//!
//! Samples come at a fixed rate (default 150 Hz, the paper's tablet): sample `k` is at
//! `k * 1000 / rate_hz` ms. Coordinates are px, with the shape's bounding box about `size` px on
//! its longer side and starting near `(0.1 size, 0.1 size)`. The same parameters and seed give
//! the same stroke.

use std::f64::consts::{PI, TAU};
use std::str::FromStr;

use glam::DVec2;
use serde::{Deserialize, Serialize};

use crate::acuts::ParamError;
use crate::model::{Sample, Stroke};

/// Default sampling rate: the paper's 150 Hz tablet.
pub const DEFAULT_SAMPLE_RATE_HZ: f64 = 150.0;
/// Default average speed, px/s (table 4's typical 300 px/s).
pub const DEFAULT_SPEED_PX_PER_S: f64 = 300.0;
/// Default size (longer side of the bounding box), px.
pub const DEFAULT_SHAPE_SIZE_PX: f64 = 300.0;
/// The most samples one generated stroke may have.
pub const MAX_GENERATED_SAMPLES: usize = 1_000_000;

/// A shape to draw.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Hash,
    Serialize,
    Deserialize,
    strum::IntoStaticStr,
    strum::Display,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Shape {
    /// A figure-8 drawn in one closed stroke.
    Figure8,
    /// Four semicircles in a row, alternating up and down.
    Semicircles,
    /// A closed, elongated outline pinched in the middle.
    Chromosome,
    /// A short stem, then a pointed leaf outline with a gently serrated edge.
    Leaf,
    /// Cursive-like loops of varying height along a drifting baseline.
    Scribble,
}

impl Shape {
    /// Every shape, in a fixed order.
    pub const ALL: [Shape; 5] =
        [Shape::Figure8, Shape::Semicircles, Shape::Chromosome, Shape::Leaf, Shape::Scribble];

    /// The shape's name, as [`FromStr`] reads it.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// A shape name that [`Shape::from_str`] does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown shape {name:?}: expected one of figure8, semicircles, chromosome, leaf, scribble")]
pub struct UnknownShapeError {
    pub name: String,
}

impl FromStr for Shape {
    type Err = UnknownShapeError;

    /// Reads a shape name, case-insensitively; `figure-8` and `figure_8` are accepted too.
    fn from_str(name: &str) -> Result<Shape, UnknownShapeError> {
        let key: String = name.trim().to_ascii_lowercase().replace(['-', '_'], "");
        Shape::ALL
            .into_iter()
            .find(|shape| shape.name() == key)
            .ok_or_else(|| UnknownShapeError { name: name.to_string() })
    }
}

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeneratorParams {
    pub shape: Shape,
    /// Average speed, px/s (path length over duration).
    pub speed: f64,
    /// Longer side of the shape's bounding box, px.
    pub size: f64,
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    pub seed: u64,
}

impl Default for GeneratorParams {
    fn default() -> GeneratorParams {
        GeneratorParams {
            shape: Shape::Figure8,
            speed: DEFAULT_SPEED_PX_PER_S,
            size: DEFAULT_SHAPE_SIZE_PX,
            rate_hz: DEFAULT_SAMPLE_RATE_HZ,
            seed: 0,
        }
    }
}

impl GeneratorParams {
    /// Refuses speeds, sizes and rates that are not positive and finite or that are absurd.
    pub fn validate(&self) -> Result<(), ParamError> {
        let check = |name, value: f64, lo: f64, hi: f64, range| {
            if value.is_finite() && value >= lo && value <= hi {
                Ok(())
            } else {
                Err(ParamError { name, value, range })
            }
        };
        check("speed", self.speed, 1.0, 100_000.0, "[1, 100000] px/s")?;
        check("size", self.size, 1.0, 100_000.0, "[1, 100000] px")?;
        check("rate_hz", self.rate_hz, 1.0, 10_000.0, "[1, 10000] Hz")?;
        Ok(())
    }
}

/// SplitMix64 (Steele, Lea, Flood 2014): a tiny, good-enough PRNG for generated strokes.
#[derive(Debug, Clone)]
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }

    /// Uniform integer in `lo..=hi`.
    fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as usize
    }

    /// Standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.next_f64(); // (0, 1]
        let u2 = self.next_f64();
        (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    }
}

/// Correlated noise: `n_k = rho n_{k-1} + sigma sqrt(1 - rho²) xi_k`, stationary deviation
/// `sigma`.
#[derive(Debug, Clone)]
struct Ar1 {
    rho: f64,
    sigma: f64,
    value: f64,
}

impl Ar1 {
    fn new(rho: f64, sigma: f64, rng: &mut SplitMix64) -> Ar1 {
        Ar1 { rho, sigma, value: sigma * rng.normal() }
    }

    fn next(&mut self, rng: &mut SplitMix64) -> f64 {
        self.value =
            self.rho * self.value + self.sigma * (1.0 - self.rho * self.rho).sqrt() * rng.normal();
        self.value
    }
}

const JITTER_PX: f64 = 0.35;
const JITTER_RHO: f64 = 0.85;
/// Points of the dense polyline a contour is traced from.
const N_DENSE: usize = 6000;
/// Share of the path length over which the pen speeds up from rest (and slows down to rest).
const RAMP_SHARE: f64 = 0.06;

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// The shape's contour as a dense polyline in its own units (any scale).
fn contour(shape: Shape, rng: &mut SplitMix64) -> Vec<DVec2> {
    let at = |i: usize| i as f64 / (N_DENSE - 1) as f64;
    match shape {
        Shape::Figure8 => (0..N_DENSE)
            .map(|i| {
                // Starts at the top, crosses in the middle.
                let theta = TAU * at(i) + PI / 2.0;
                DVec2::new(0.5 * (2.0 * theta).sin(), -theta.sin())
            })
            .collect(),
        Shape::Semicircles => {
            const N_ARCS: usize = 4;
            (0..N_DENSE)
                .map(|i| {
                    let u = at(i) * N_ARCS as f64;
                    let arc = (u.floor() as usize).min(N_ARCS - 1);
                    let f = u - arc as f64;
                    let side = if arc % 2 == 0 { -1.0 } else { 1.0 };
                    DVec2::new(2.0 * arc as f64 + 1.0 - (PI * f).cos(), side * (PI * f).sin())
                })
                .collect()
        }
        Shape::Chromosome => (0..N_DENSE)
            .map(|i| {
                let theta = TAU * at(i);
                let (sin, cos) = theta.sin_cos();
                DVec2::new(0.7 * sin * (0.25 + 0.75 * cos * cos), -cos)
            })
            .collect(),
        Shape::Leaf => {
            let edge = |s: f64| {
                let half_width = 0.32 * (PI * s).sin() * (1.0 - 0.35 * s);
                half_width + 0.012 * (10.0 * PI * s).sin() * (PI * s).sin()
            };
            let n_stem = N_DENSE / 10;
            let n_half = (N_DENSE - n_stem) / 2;
            let stem = (0..n_stem).map(|i| DVec2::new(-0.2 + 0.2 * i as f64 / n_stem as f64, 0.0));
            let upper = (0..n_half).map(|i| {
                let s = i as f64 / n_half as f64;
                DVec2::new(s, -edge(s))
            });
            let lower = (0..=n_half).map(|i| {
                let s = 1.0 - i as f64 / n_half as f64;
                DVec2::new(s, edge(s))
            });
            stem.chain(upper).chain(lower).collect()
        }
        Shape::Scribble => {
            let n_loops = rng.int(5, 8);
            let heights: Vec<f64> = (0..=n_loops + 1).map(|_| rng.uniform(0.45, 1.2)).collect();
            let drift_phase = rng.uniform(0.0, TAU);
            (0..N_DENSE * 2)
                .map(|i| {
                    let theta = TAU * n_loops as f64 * i as f64 / (N_DENSE * 2 - 1) as f64;
                    let loop_pos = theta / TAU;
                    let k = loop_pos.floor() as usize;
                    let f = smoothstep(loop_pos - k as f64);
                    let height = heights[k] * (1.0 - f) + heights[k + 1] * f;
                    let y = -height * 0.5 * (1.0 - theta.cos())
                        + 0.08 * (0.6 * theta / TAU + drift_phase).sin();
                    let x = 0.09 * theta - 0.25 * theta.sin() - 0.25 * y;
                    DVec2::new(x, y)
                })
                .collect()
        }
    }
}

/// Rotates, stretches, scales and places the contour: longer bbox side `size`, bbox corner at
/// `(0.1 size, 0.1 size)`.
fn place(points: &mut [DVec2], size: f64, rng: &mut SplitMix64) {
    let rotation = DVec2::from_angle(rng.uniform(-4.0, 4.0).to_radians());
    let stretch = DVec2::new(rng.uniform(0.95, 1.05), rng.uniform(0.95, 1.05));
    for p in points.iter_mut() {
        *p = rotation.rotate(*p * stretch);
    }
    let (min, max) = points
        .iter()
        .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    let scale = size / (max - min).max_element();
    for p in points.iter_mut() {
        *p = (*p - min) * scale + DVec2::splat(0.1 * size);
    }
}

/// The path with, at each vertex, its arc length and relative speed `w` (power law and ramps).
struct Path {
    points: Vec<DVec2>,
    arc: Vec<f64>,
    speed: Vec<f64>,
}

impl Path {
    fn new(points: Vec<DVec2>, size: f64) -> Path {
        let mut deduped: Vec<DVec2> = Vec::with_capacity(points.len());
        for p in points {
            if deduped.last().is_none_or(|last| last.distance(p) > 1e-9 * size) {
                deduped.push(p);
            }
        }
        let points = deduped;
        let n = points.len();
        let mut arc = vec![0.0; n];
        for i in 1..n {
            arc[i] = arc[i - 1] + points[i].distance(points[i - 1]);
        }
        let length = arc[n - 1];
        // Curvature: turning angle over the mean of the two adjacent segment lengths.
        let mut curvature = vec![0.0; n];
        for i in 1..n - 1 {
            let (d_in, d_out) = (points[i] - points[i - 1], points[i + 1] - points[i]);
            let turn = d_in.angle_to(d_out).abs();
            curvature[i] = turn / (0.5 * (d_in.length() + d_out.length()));
        }
        curvature[0] = curvature.get(1).copied().unwrap_or(0.0);
        curvature[n - 1] = curvature[n.saturating_sub(2)];
        // Smooth over a few vertices, as a hand cannot change speed instantly.
        const HALF_WINDOW: usize = 8;
        let smoothed: Vec<f64> = (0..n)
            .map(|i| {
                let window =
                    &curvature[i.saturating_sub(HALF_WINDOW)..(i + HALF_WINDOW + 1).min(n)];
                window.iter().sum::<f64>() / window.len() as f64
            })
            .collect();
        let ramp_length = RAMP_SHARE * length;
        let speed = (0..n)
            .map(|i| {
                let k = smoothed[i].clamp(1.0 / size, 100.0 / size);
                let ramp = if ramp_length > 0.0 {
                    smoothstep(arc[i] / ramp_length) * smoothstep((length - arc[i]) / ramp_length)
                } else {
                    1.0
                };
                k.powf(-1.0 / 3.0) * (0.2 + 0.8 * ramp)
            })
            .collect();
        Path { points, arc, speed }
    }

    fn length(&self) -> f64 {
        self.arc[self.arc.len() - 1]
    }

    /// Position and relative speed at `n_steps + 1` evenly timed instants from start to end.
    fn timed(&self, n_steps: usize) -> Vec<(DVec2, f64)> {
        let n = self.points.len();
        // Time to cross each segment: length over the mean relative speed of its ends.
        let mut time = vec![0.0; n];
        for i in 1..n {
            let ds = self.arc[i] - self.arc[i - 1];
            time[i] = time[i - 1] + ds / (0.5 * (self.speed[i] + self.speed[i - 1]));
        }
        let total = time[n - 1];
        let mut segment = 1;
        (0..=n_steps)
            .map(|k| {
                let target = total * k as f64 / n_steps as f64;
                while segment < n - 1 && time[segment] < target {
                    segment += 1;
                }
                if n == 1 {
                    return (self.points[0], self.speed[0]);
                }
                let (t0, t1) = (time[segment - 1], time[segment]);
                let f = if t1 > t0 { ((target - t0) / (t1 - t0)).clamp(0.0, 1.0) } else { 1.0 };
                let position = self.points[segment - 1].lerp(self.points[segment], f);
                let speed = self.speed[segment - 1] * (1.0 - f) + self.speed[segment] * f;
                (position, speed)
            })
            .collect()
    }
}

/// Generates one stroke (see the module documentation). Refuses bad parameters, and parameters
/// that would make more than [`MAX_GENERATED_SAMPLES`] samples.
pub fn generate_stroke(params: &GeneratorParams) -> Result<Stroke, ParamError> {
    params.validate()?;
    let mut rng =
        SplitMix64(params.seed ^ (params.shape as u64).wrapping_mul(0xA076_1D64_78BD_642F));
    let mut points = contour(params.shape, &mut rng);
    place(&mut points, params.size, &mut rng);
    let path = Path::new(points, params.size);

    // Sample intervals in all: path length over average speed, at the sampling rate.
    let n_intervals_f = (path.length() / params.speed * params.rate_hz).round().max(2.0);
    if n_intervals_f >= MAX_GENERATED_SAMPLES as f64 {
        return Err(ParamError {
            name: "samples (path length / speed * rate_hz)",
            value: n_intervals_f,
            range: "[1, 1000000]",
        });
    }
    let n_intervals = n_intervals_f as usize;
    let n_down = rng.int(3, 5).min(n_intervals / 5);
    let n_up = rng.int(2, 4).min(n_intervals / 5);
    let n_move = n_intervals - n_down - n_up;

    let moving = path.timed(n_move);
    let mean_speed = moving.iter().map(|(_, v)| v).sum::<f64>() / moving.len() as f64;
    let start = moving[0].0;
    let end = moving[moving.len() - 1].0;
    let positions: Vec<(DVec2, f64)> = std::iter::repeat_n((start, 0.0), n_down)
        .chain(moving)
        .chain(std::iter::repeat_n((end, 0.0), n_up))
        .collect();

    // Pressure: peak level, slow periodic variation, speed coupling, noise, ramps at both ends.
    let peak = rng.uniform(0.5, 0.7);
    let periodic = match params.shape {
        Shape::Semicircles | Shape::Leaf => 0.12,
        _ => 0.05,
    };
    let (f1, phase1) = (rng.uniform(1.0, 2.0), rng.uniform(0.0, TAU));
    let (f2, phase2) = (rng.uniform(3.0, 6.0), rng.uniform(0.0, TAU));
    let mut pressure_noise = Ar1::new(0.9, 0.012, &mut rng);
    let (mut jitter_x, mut jitter_y) =
        (Ar1::new(JITTER_RHO, JITTER_PX, &mut rng), Ar1::new(JITTER_RHO, JITTER_PX, &mut rng));

    let period_ms = 1000.0 / params.rate_hz;
    let last = (positions.len() - 1) as f64;
    let samples: Vec<Sample> = positions
        .iter()
        .enumerate()
        .map(|(k, &(position, speed))| {
            let g = k as f64 / last;
            let envelope = 0.1 + 0.9 * smoothstep(g / 0.12) * smoothstep((1.0 - g) / 0.12);
            let variation = 1.0
                + periodic * (TAU * f1 * g + phase1).sin()
                + 0.4 * periodic * (TAU * f2 * g + phase2).sin();
            let speed_factor = if speed > 0.0 {
                (1.0 - 0.15 * (speed / mean_speed - 1.0)).clamp(0.8, 1.2)
            } else {
                1.0
            };
            let p = (peak * envelope * variation * speed_factor + pressure_noise.next(&mut rng))
                .clamp(0.01, 1.0);
            let x = position.x + jitter_x.next(&mut rng);
            let y = position.y + jitter_y.next(&mut rng);
            Sample::new(x, y, k as f64 * period_ms, p)
        })
        .collect();
    Ok(Stroke::new(samples).expect("generated samples are finite, timed forward, p in [0.01, 1]"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::polyline_length;

    fn params(shape: Shape, speed: f64, seed: u64) -> GeneratorParams {
        GeneratorParams { shape, speed, seed, ..GeneratorParams::default() }
    }

    #[test]
    // The same parameters and seed give the same stroke; another seed gives another.
    fn deterministic_for_a_seed() {
        for shape in Shape::ALL {
            let a = generate_stroke(&params(shape, 300.0, 7)).unwrap();
            let b = generate_stroke(&params(shape, 300.0, 7)).unwrap();
            let c = generate_stroke(&params(shape, 300.0, 8)).unwrap();
            assert_eq!(a, b, "{shape}");
            assert_ne!(a, c, "{shape}");
        }
    }

    #[test]
    // Every shape at table 4's speeds: average speed within 30 %, pressure in (0, 1], times on
    // the sample clock, size about as asked.
    fn strokes_look_as_asked() {
        for shape in Shape::ALL {
            for speed in [200.0, 300.0, 400.0, 500.0] {
                for seed in 0..3 {
                    let p = params(shape, speed, seed);
                    let stroke = generate_stroke(&p).unwrap();
                    let samples = stroke.samples();
                    let duration_s = samples[samples.len() - 1].t / 1000.0;
                    let measured = polyline_length(samples) / duration_s;
                    let what = format!("{shape} at {speed} px/s, seed {seed}");
                    assert!((measured / speed - 1.0).abs() < 0.3, "{what}: {measured} px/s");
                    assert!(samples.iter().all(|s| s.p > 0.0 && s.p <= 1.0), "{what}");
                    let period = 1000.0 / p.rate_hz;
                    for (k, s) in samples.iter().enumerate() {
                        assert_eq!(s.t, k as f64 * period, "{what}");
                    }
                    let (lo, hi) = samples.iter().fold((f64::MAX, f64::MIN), |(lo, hi), s| {
                        (lo.min(s.x.min(s.y)), hi.max(s.x.max(s.y)))
                    });
                    assert!(lo > 0.0 && hi < 1.3 * p.size, "{what}: {lo}..{hi}");
                    assert!(samples.len() > 100, "{what}: {} samples", samples.len());
                }
            }
        }
    }

    #[test]
    // The pen slows in curves: on the leaf, the slowest steps are far slower than the fastest.
    fn speed_follows_curvature() {
        let stroke = generate_stroke(&params(Shape::Leaf, 300.0, 1)).unwrap();
        let steps: Vec<f64> = stroke.samples().windows(2).map(|w| w[0].distance(&w[1])).collect();
        let middle = &steps[steps.len() / 10..steps.len() * 9 / 10];
        let max = middle.iter().copied().fold(0.0, f64::max);
        let min = middle.iter().copied().fold(f64::MAX, f64::min);
        assert!(max > 3.0 * min, "step lengths {min}..{max}");
    }

    #[test]
    // Pressure ramps up at pen-down and tapers at pen-up.
    fn pressure_ramps_and_tapers() {
        for shape in Shape::ALL {
            let stroke = generate_stroke(&params(shape, 300.0, 3)).unwrap();
            let p: Vec<f64> = stroke.samples().iter().map(|s| s.p).collect();
            let middle = p[p.len() / 2];
            assert!(p[0] < 0.5 * middle && p[p.len() - 1] < 0.5 * middle, "{shape}: {p:?}");
        }
    }

    #[test]
    // Shape names read back from Display, with a few spellings, and unknown names are refused.
    fn shape_names() {
        for shape in Shape::ALL {
            assert_eq!(shape.to_string().parse::<Shape>(), Ok(shape));
        }
        assert_eq!("Figure-8".parse::<Shape>(), Ok(Shape::Figure8));
        let err = "circle".parse::<Shape>().unwrap_err();
        assert!(err.to_string().contains("unknown shape \"circle\""), "{err}");
    }

    #[test]
    // Bad parameters are refused by name.
    fn refuses_bad_params() {
        let cases = [
            (GeneratorParams { speed: 0.0, ..GeneratorParams::default() }, "speed"),
            (GeneratorParams { size: f64::NAN, ..GeneratorParams::default() }, "size"),
            (GeneratorParams { rate_hz: -150.0, ..GeneratorParams::default() }, "rate_hz"),
            (
                GeneratorParams { size: 100_000.0, speed: 1.0, ..GeneratorParams::default() },
                "samples",
            ),
        ];
        for (params, name) in cases {
            let err = generate_stroke(&params).unwrap_err();
            assert!(err.name.starts_with(name), "{err}");
        }
    }
}
