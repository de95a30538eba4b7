//! penmesh core: the stroke model, ACUTS simplification, LRPDP stroke meshes, GLB export,
//! metrics, file formats, a stroke generator and the wire protocol.
//!
//! **This crate does no I/O**: no files, no network, no async. Everything here is a pure function
//! or a state machine, so the proxy, the client and the tests share one implementation. The
//! one exception is [`data_sets`], which finds and reads the recorded pen data sets in place for
//! the tests, the benches and `penmesh-lab eval`.

mod acuts;
pub mod baselines;
pub mod centreline;
mod cloud;
pub mod data_sets;
mod formats;
mod generator;
mod glb;
mod lrpdp;
mod mesh;
mod mesh_path;
mod metrics;
mod model;
mod placement;
mod prism;
pub mod protocol;
mod region;
mod scene;
mod solid;
mod svg;

pub use crate::acuts::{
    AcutsOutput, AcutsParams, DEFAULT_ANGLE_DEG, DEFAULT_PRESSURE_TOLERANCE,
    DEFAULT_RESAMPLE_DISTANCE, DEFAULT_TOLERANCE, Kept, PAPER_PRESSURE_VARIANCE,
    PAPER_RESAMPLE_DISTANCE, ParamError, PressureGate, Released, Resampler, Simplifier, acuts,
    pressure_variance, resample, segment_distance, simplify,
};
pub use crate::model::{
    Brush, BrushError, MAX_COORDINATE, Sample, SampleError, Stroke, polyline_length,
    validate_sample, validate_samples,
};

pub use crate::centreline::{Centreline, SmoothOptions, fit_centreline, smooth_centreline};
pub use crate::cloud::{
    CloudOptions, DEFAULT_CLOUD_DEPTH_FACTOR, DEFAULT_CLOUD_DIVISIONS, PointCloud, point_cloud,
    point_cloud_ply,
};
pub use crate::formats::{
    FormatError, HWR_PERIOD_MS, SVC2004_GAP_MS, StrokeFormat, TABLET_PRESSURE_LEVELS, read_csv,
    read_hwr, read_json, read_strokes, read_svc2004, write_csv, write_json,
};
pub use crate::generator::{
    DEFAULT_SAMPLE_RATE_HZ, DEFAULT_SHAPE_SIZE_PX, DEFAULT_SPEED_PX_PER_S, GeneratorParams,
    MAX_GENERATED_SAMPLES, Shape, UnknownShapeError, generate_stroke,
};
pub use crate::glb::{
    EXT_MESHOPT_COMPRESSION, GlbEncoding, GlbMeta, GlbOptions, GlbStroke, KHR_MESH_QUANTIZATION,
    POSITION_STEP, stroke_glb, strokes_glb,
};
pub use crate::lrpdp::{
    KeptError, MIN_CAP_POINTS, Outline, OutlineOptions, PIXEL_TOLERANCE, fitted_outline, outline,
};
pub use crate::mesh::{
    DEFAULT_THICKNESS, MAX_MERGED_PIECES, MAX_MERGED_TURN_DEG, MIN_THICKNESS, MeshDefect,
    MeshStats, SolidOptions, StrokeMesh, is_closed, mesh_defect, signed_volume, solid_mesh,
    stroke_mesh, visible_centres,
};
pub use crate::mesh_path::{
    MeshError, MeshedStroke, mesh_drawn_solid, mesh_drawn_stroke, mesh_retained_solid,
    mesh_retained_stroke, solid_of_outline,
};
pub use crate::metrics::{
    MetricsError, SimplificationMetrics, cdf_error_area, e_max, p_max, pressure_error,
    simplification_metrics,
};
pub use crate::placement::{
    IDENTITY_MATRIX, MAX_SCALE, MAX_TRANSLATION, MIN_SCALE, Placement, PlacementError,
    SIMILARITY_TOLERANCE,
};
pub use crate::prism::{PrismVertices, prism_mesh};
pub use crate::region::{
    Contour, Polygon, filled_region, ink_region, region_area, signed_area, solid_region,
};
pub use crate::scene::{
    Author, EXTRAS_KEY, ImportedFrom, ReadStroke, SCENE_EXTRAS_KEY, SCENE_FORMAT_VERSION,
    SceneError, SceneExtras, SceneInput, SceneStroke, StrokeExtras, read_scene, scene_glb,
    stroke_label,
};
pub use crate::solid::{
    CLOSURE_WIDTHS, MAX_DEPTH, MIN_DEPTH, Solid, SolidError, SolidKind, closure_gap,
};
pub use crate::svg::{SvgStroke, simplification_svg, strokes_svg};
