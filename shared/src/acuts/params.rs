//! The parameters of ACUTS, their defaults and their validation.

use serde::{Deserialize, Serialize};

/// Default chord-length threshold `l_eps` of stage 1, px: 0, stage 1 keeps every sample. The
/// paper's table 3 has 1.0, which spends more than half of the guaranteed bound
/// `d_d + l_eps = 1.74` px on stage 1 (about twice the optimum, `docs/results.md`); any
/// `l_eps > 0` also drops samples whatever their pressure (a pen-up tail loses its pressure fall
/// within a fraction of a pixel), so the pressure bound of stage 2 would not hold end to end.
/// With 0 the whole budget goes to stage 2 and both bounds hold end to end.
pub const DEFAULT_RESAMPLE_DISTANCE: f64 = 0.0;
/// Default chord-height tolerance `d_d` (same unit as x, y; table 3: 0.74): the paper's
/// guaranteed bound of 1.74 px, all of it for stage 2 (see [`DEFAULT_RESAMPLE_DISTANCE`]).
pub const DEFAULT_TOLERANCE: f64 = 1.74;
// The defaults keep the guaranteed bound of the paper's setting, d_d + l_eps = 0.74 + 1.0 px,
// checked when the crate compiles.
const _: () = assert!(
    (DEFAULT_TOLERANCE + DEFAULT_RESAMPLE_DISTANCE
        - (AcutsParams::paper().tolerance + PAPER_RESAMPLE_DISTANCE))
        .abs()
        < 1e-12
);
/// Default angle threshold `d_alpha` in degrees (table 3: 15°). At 15° the angle test, not the
/// distance, retains most samples near the anchor, where pen jitter makes directions noisy; 45°
/// still keeps every skipped sample beyond `d_d` of the anchor within 45° of the retained
/// chord's direction (see [`AcutsParams::angle_near_anchor`]).
pub const DEFAULT_ANGLE_DEG: f64 = 45.0;
/// Default pressure tolerance `delta_p` of the interpolation gate ([`PressureGate`]), for `p`
/// in `[0, 1]`: every removed sample's pressure lies within 0.2 of the pressure interpolated
/// (linearly in time) along its retained segment. With the default brush (radius `8 · 0.5 · p`
/// px) that is 0.8 px of radius, under half of the default 1.74 px bound on position. (The
/// paper's variance gate at the former default 0.01 bounded nothing and let 0.27 through on
/// SVC2004.)
pub const DEFAULT_PRESSURE_TOLERANCE: f64 = 0.2;
/// The pressure-variance threshold `d_sigma2` of the paper's table 3 (1500 on a 1024-level
/// tablet, rescaled to `p` in `[0, 1]`), for [`PressureGate::Variance`].
pub const PAPER_PRESSURE_VARIANCE: f64 = 0.0015;
/// The stage-1 distance `l_eps` of the paper's table 3, px.
pub const PAPER_RESAMPLE_DISTANCE: f64 = 1.0;

/// What stage 2 asks of the pressure of the samples it removes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum PressureGate {
    /// The paper's gate (formula 3, `W_s = 3`): the candidate `m` is retained when the
    /// population variance of the pressures of `{a, m, e}` exceeds this threshold `d_sigma2`.
    /// A drift heuristic: it bounds no error.
    Variance(f64),
    /// The interpolation test (the default): `m` is removed only if every skipped `q` in
    /// `R ∪ {m}` has `|p_q - lerp(p_a, p_e, tau_q)| <= delta_p`, this value, with
    /// `tau_q = (t_q - t_a) / (t_e - t_a)`. A guarantee: stage 2's pressure error is at most
    /// `delta_p`, measured as `penmesh-lab eval`'s `P_max`.
    Interpolation(f64),
}

/// Stage-2 parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct AcutsParams {
    /// Chord-height tolerance `d_d`.
    pub tolerance: f64,
    /// Angle threshold `d_alpha`, degrees.
    pub angle_deg: f64,
    /// Whether the angle test also applies to skipped samples within `d_d` of the anchor (the
    /// paper's test: `true`). The default, `false`, leaves them to the distance test: such a
    /// sample lies within `d_d` of every segment from the anchor, and its direction from the
    /// anchor is pen jitter at that scale (on the Dutch signatures the angle test there was the
    /// largest geometric cost, `docs/results.md`).
    pub angle_near_anchor: bool,
    /// The pressure gate.
    pub pressure: PressureGate,
}

impl Default for AcutsParams {
    fn default() -> AcutsParams {
        AcutsParams {
            tolerance: DEFAULT_TOLERANCE,
            angle_deg: DEFAULT_ANGLE_DEG,
            angle_near_anchor: false,
            pressure: PressureGate::Interpolation(DEFAULT_PRESSURE_TOLERANCE),
        }
    }
}

impl AcutsParams {
    /// The setting of the paper's table 3 (with [`PAPER_RESAMPLE_DISTANCE`] for stage 1):
    /// `d_d` 0.74, 15°, the angle test near the anchor, the variance gate at 0.0015.
    pub const fn paper() -> AcutsParams {
        AcutsParams {
            tolerance: 0.74,
            angle_deg: 15.0,
            angle_near_anchor: true,
            pressure: PressureGate::Variance(PAPER_PRESSURE_VARIANCE),
        }
    }
}

/// A parameter outside its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} is outside {range}")]
pub struct ParamError {
    pub name: &'static str,
    pub value: f64,
    pub range: &'static str,
}

impl AcutsParams {
    /// Parameters checked on construction: an out-of-range value is refused with its name.
    pub fn new(
        tolerance: f64,
        angle_deg: f64,
        angle_near_anchor: bool,
        pressure: PressureGate,
    ) -> Result<AcutsParams, ParamError> {
        let params = AcutsParams { tolerance, angle_deg, angle_near_anchor, pressure };
        params.validate()?;
        Ok(params)
    }

    /// Checks every parameter against its range (`tolerance` and the pressure threshold
    /// finite and `>= 0`, `angle_deg` in `[0, 90]`).
    pub fn validate(&self) -> Result<(), ParamError> {
        let bad = |name, value: f64, ok: bool, range| {
            if ok && value.is_finite() { Ok(()) } else { Err(ParamError { name, value, range }) }
        };
        bad("tolerance", self.tolerance, self.tolerance >= 0.0, "[0, inf)")?;
        bad("angle_deg", self.angle_deg, (0.0..=90.0).contains(&self.angle_deg), "[0, 90]")?;
        match self.pressure {
            PressureGate::Variance(v) => bad("pressure.variance", v, v >= 0.0, "[0, inf)"),
            PressureGate::Interpolation(d) => {
                bad("pressure.interpolation", d, d >= 0.0, "[0, inf)")
            }
        }
    }
}
