//! The algorithms `--algos` names: ACUTS in its two settings and the baselines, each run at a
//! guaranteed bound.

use super::*;

/// The ACUTS settings `--algos` knows, before the baselines ([`BASELINE_NAMES`]).
pub(super) const ACUTS_NAMES: [&str; 2] = ["acuts", "acuts-paper"];
pub(super) const DEFAULT_ALGOS: &str =
    "acuts,acuts-paper,dp,vw,window,window-p,squish-e,bqs,fbqs,dpts,optimal,optimal-p";
/// The ACUTS setting of the paper's table 3 and the spec (`acuts-paper`), for before/after
/// comparisons: d_d, l_eps, d_alpha (near the anchor too), d_sigma2.
pub(super) const PAPER: AcutsParams = AcutsParams::paper();
pub(super) const PAPER_RESAMPLE: f64 = penmesh::PAPER_RESAMPLE_DISTANCE;

/// An algorithm under evaluation, run at a guaranteed bound.
pub enum Method {
    /// ACUTS with its setting; at another bound, `d_d` and `l_eps` are scaled together.
    Acuts {
        resample: f64,
        params: AcutsParams,
    },
    Baseline(Box<dyn Simplify>),
}

impl std::fmt::Debug for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Method::Acuts { resample, params } => {
                write!(f, "Acuts {{ resample: {resample}, params: {params:?} }}")
            }
            Method::Baseline(b) => write!(f, "Baseline({})", b.name()),
        }
    }
}

#[derive(Debug)]
pub struct Algo {
    pub name: String,
    pub online: bool,
    pub method: Method,
}

impl Algo {
    /// The kept indices with every removed sample guaranteed within `bound`.
    pub fn run(&self, samples: &[Sample], bound: f64) -> Vec<usize> {
        match &self.method {
            Method::Acuts { resample, params } => {
                let (tolerance, resample) = split_bound(params.tolerance, *resample, bound);
                let params = AcutsParams { tolerance, ..*params };
                penmesh::acuts(samples, resample, &params).kept
            }
            Method::Baseline(b) => b.run(samples, bound),
        }
    }
}

/// `(d_d, l_eps)` scaled so that they add up to `bound`, in the ratio of the setting.
pub(super) fn split_bound(tolerance: f64, resample: f64, bound: f64) -> (f64, f64) {
    let total = tolerance + resample;
    if total > 0.0 { (bound * tolerance / total, bound * resample / total) } else { (bound, 0.0) }
}

/// Builds the algorithms named in `names`.
pub fn algos(names: &[String], args_acuts: (f64, AcutsParams)) -> anyhow::Result<Vec<Algo>> {
    names
        .iter()
        .map(|name| {
            let name = name.trim().to_ascii_lowercase();
            // The pressure-aware baselines bound pressure as ACUTS's interpolation gate does.
            let pressure_tolerance = match args_acuts.1.pressure {
                penmesh::PressureGate::Interpolation(d) => d,
                penmesh::PressureGate::Variance(_) => penmesh::DEFAULT_PRESSURE_TOLERANCE,
            };
            let (online, method) = match name.as_str() {
                "acuts" => (true, Method::Acuts { resample: args_acuts.0, params: args_acuts.1 }),
                "acuts-paper" => (true, Method::Acuts { resample: PAPER_RESAMPLE, params: PAPER }),
                other => {
                    let b = baseline(other, pressure_tolerance).ok_or_else(|| {
                        anyhow::anyhow!(
                            "unknown algorithm {other:?}: expected one of {}",
                            ACUTS_NAMES
                                .iter()
                                .chain(&BASELINE_NAMES)
                                .copied()
                                .collect::<Vec<_>>()
                                .join(", ")
                        )
                    })?;
                    (b.is_online(), Method::Baseline(b))
                }
            };
            Ok(Algo { name, online, method })
        })
        .collect()
}
