//! Flags that several commands share: the proxy to talk to, the ACUTS setting and the stroke
//! generator's.

use clap::Args;

/// Where the commands that talk to a proxy (draw, export, import) find the session.
#[derive(Debug, Clone, Args)]
pub struct ConnectionArgs {
    /// The proxy, e.g. http://127.0.0.1:8080.
    #[arg(long, env = "PENMESH_SERVER")]
    pub server: String,
    /// The session id (from POST /v1/sessions or `penmesh-lab demo --keep-serving`).
    #[arg(long, env = "PENMESH_SESSION")]
    pub session: uuid::Uuid,
    /// The session's bearer token.
    #[arg(long, env = "PENMESH_TOKEN", hide_env_values = true)]
    pub token: String,
}

impl ConnectionArgs {
    pub fn endpoint(&self) -> anyhow::Result<crate::endpoint::Endpoint> {
        crate::endpoint::Endpoint::new(&self.server, self.session, self.token.clone())
    }
}

/// ACUTS settings shared by the commands that simplify.
#[derive(Debug, Clone, Args)]
pub struct AcutsArgs {
    /// Chord-height tolerance d_d, in the stroke's unit.
    #[arg(long, default_value_t = penmesh::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Angle threshold d_alpha, in degrees.
    #[arg(long, default_value_t = penmesh::DEFAULT_ANGLE_DEG)]
    pub angle: f64,
    /// Also ask the angle of skipped samples within d_d of the anchor (the paper's test).
    #[arg(long)]
    pub angle_near_anchor: bool,
    /// Pressure tolerance delta_p (pressure in [0, 1]): every removed sample's pressure within
    /// this of the pressure interpolated in time along its retained segment.
    #[arg(long, default_value_t = penmesh::DEFAULT_PRESSURE_TOLERANCE)]
    pub pressure_tolerance: f64,
    /// Use the paper's pressure-variance gate (formula 3) with this threshold d_sigma2 instead
    /// of the pressure tolerance (the paper: 0.0015).
    #[arg(long = "pressure-var", conflicts_with = "pressure_tolerance")]
    pub pressure_var: Option<f64>,
    /// Stage-1 chord-length resampling distance l_eps; 0 turns resampling off.
    #[arg(long, default_value_t = penmesh::DEFAULT_RESAMPLE_DISTANCE)]
    pub resample: f64,
}

/// The pressure gate the flags pick: `--pressure-var` if given, else `--pressure-tolerance`.
pub fn pressure_gate(tolerance: f64, variance: Option<f64>) -> penmesh::PressureGate {
    match variance {
        Some(v) => penmesh::PressureGate::Variance(v),
        None => penmesh::PressureGate::Interpolation(tolerance),
    }
}

impl AcutsArgs {
    pub fn params(&self) -> anyhow::Result<penmesh::AcutsParams> {
        let params = penmesh::AcutsParams::new(
            self.tolerance,
            self.angle,
            self.angle_near_anchor,
            pressure_gate(self.pressure_tolerance, self.pressure_var),
        )
        .map_err(|e| anyhow::anyhow!("bad ACUTS setting: {e}"))?;
        anyhow::ensure!(
            self.resample.is_finite() && self.resample >= 0.0,
            "bad ACUTS setting: resample = {} must be a finite number >= 0",
            self.resample
        );
        Ok(params)
    }
}

/// How generated strokes are drawn: shared by `synth` and `draw --synth`.
#[derive(Debug, Clone, Args)]
pub struct GeneratorArgs {
    /// Generated strokes: average pen speed, px/s (the paper's table 4 uses 200 to 500).
    #[arg(long, default_value_t = penmesh::DEFAULT_SPEED_PX_PER_S)]
    pub speed: f64,
    /// Generated strokes: longer side of the shape's bounding box, px.
    #[arg(long, default_value_t = penmesh::DEFAULT_SHAPE_SIZE_PX)]
    pub size: f64,
    /// Generated strokes: tablet sampling rate, Hz.
    #[arg(long, default_value_t = penmesh::DEFAULT_SAMPLE_RATE_HZ)]
    pub rate: f64,
    /// Generated strokes: seed of the hand's jitter and timing; the same seed gives the same
    /// stroke (`draw --count N` uses SEED, SEED+1, ...).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

impl GeneratorArgs {
    /// The generator's settings for `shape`, with the seed moved on by `seed_offset`.
    pub fn params(&self, shape: penmesh::Shape, seed_offset: u64) -> penmesh::GeneratorParams {
        penmesh::GeneratorParams {
            shape,
            speed: self.speed,
            size: self.size,
            rate_hz: self.rate,
            seed: self.seed.wrapping_add(seed_offset),
        }
    }
}

/// `--glb`: how a command writes its GLB files (`penmesh::GlbEncoding`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum GlbArg {
    /// Quantised and compressed with EXT_meshopt_compression (three.js: MeshoptDecoder).
    #[default]
    Meshopt,
    /// Quantised with KHR_mesh_quantization only.
    Quantized,
    /// Plain floats, for tools that decode neither extension.
    Plain,
}

impl From<GlbArg> for penmesh::GlbEncoding {
    fn from(arg: GlbArg) -> penmesh::GlbEncoding {
        match arg {
            GlbArg::Meshopt => penmesh::GlbEncoding::Meshopt,
            GlbArg::Quantized => penmesh::GlbEncoding::Quantized,
            GlbArg::Plain => penmesh::GlbEncoding::Plain,
        }
    }
}
