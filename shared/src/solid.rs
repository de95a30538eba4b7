//! What a stroke becomes (`spec/system.md`, "Solids: what a stroke becomes"; protocol 6): its
//! kind and its depth, data beside the stroke like its placement. The pen, ACUTS and LRPDP do
//! not change; the solid only says what is built from the outline LRPDP makes.
//!
//! - [`SolidKind::Line`] with no depth (the default, every stroke stored before protocol 6):
//!   today's pressure-width rod, as thick as half its width (`mesh.rs`).
//! - `Line` with a depth `D` (the paper's extrusion depth): the stroke's pressure-width ink
//!   extruded straight up from its plane, `z` from 0 to `D`: a tall, thin wall from one stroke.
//! - [`SolidKind::Filled`]: the region the stroke encloses together with its ink, one plate
//!   from `z = 0` to `D`. Only a closed stroke fills ([`closure_gap`]); a self-crossing one
//!   fills by the non-zero rule (`region.rs`).
//! - [`SolidKind::Hole`]: the same region when the stroke is closed, its ink when it is not,
//!   subtracted at export from every solid it overlaps.
//!
//! A solid is validated on construction (a `filled` or `hole` needs a depth; a depth is finite
//! and within [[`MIN_DEPTH`], [`MAX_DEPTH`]] px), so the rest of the code never sees a bad one.
//! JSON: `{"kind": "filled", "depth": 48.0}`; `{"kind": "line", "depth": null}` is the default.

use serde::{Deserialize, Serialize};

/// The thinnest solid, px: two steps of the GLB's position grid, so that a plate never
/// quantises flat.
pub const MIN_DEPTH: f64 = 0.125;
/// The deepest solid, px: ten thousand pixels, some five boards' widths.
pub const MAX_DEPTH: f64 = 10_000.0;
/// A stroke is closed when its ends lie within this many widths of each other (the width at
/// an end being twice its radius; the two ends' widths averaged).
pub const CLOSURE_WIDTHS: f64 = 3.0;

/// What a stroke becomes.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, utoipa::ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum SolidKind {
    /// The stroke's ink: the pressure-width rod, or with a depth a wall of that height.
    #[default]
    Line,
    /// The region the (closed) stroke encloses with its ink, one plate.
    Filled,
    /// Subtracted from every solid it overlaps: the filled region of a closed stroke, the ink
    /// of an open one.
    Hole,
}

impl SolidKind {
    pub const ALL: [SolidKind; 3] = [SolidKind::Line, SolidKind::Filled, SolidKind::Hole];

    pub fn name(self) -> &'static str {
        match self {
            SolidKind::Line => "line",
            SolidKind::Filled => "filled",
            SolidKind::Hole => "hole",
        }
    }

    /// The kind named `name` (`line`, `filled`, `hole`).
    pub fn parse(name: &str) -> Result<SolidKind, SolidError> {
        SolidKind::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| SolidError::UnknownKind(name.to_string()))
    }
}

impl std::fmt::Display for SolidKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A stroke's solid: its kind and its depth (px of its plane), validated.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(try_from = "UncheckedSolid")]
pub struct Solid {
    kind: SolidKind,
    /// The extrusion depth in px; `null` only for a `line`, the pressure-width rod.
    depth: Option<f64>,
}

/// A solid as it arrives, before validation.
#[derive(Deserialize)]
struct UncheckedSolid {
    kind: SolidKind,
    depth: Option<f64>,
}

impl TryFrom<UncheckedSolid> for Solid {
    type Error = SolidError;
    fn try_from(unchecked: UncheckedSolid) -> Result<Solid, SolidError> {
        Solid::new(unchecked.kind, unchecked.depth)
    }
}

/// Why a solid cannot be made. Each names what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolidError {
    #[error("unknown solid kind {0:?}: line, filled or hole")]
    UnknownKind(String),
    #[error("a {0} solid needs a depth")]
    NoDepth(SolidKind),
    #[error("the depth {0} is not a finite number")]
    NonFinite(f64),
    #[error("the depth {0} px is outside [{MIN_DEPTH}, {MAX_DEPTH}] px")]
    DepthRange(f64),
    #[error(
        "an open stroke cannot be filled: its ends are {gap:.1} px apart, and a stroke is closed \
         when they lie within {allowed:.1} px ({CLOSURE_WIDTHS} widths)"
    )]
    Open { gap: f64, allowed: f64 },
    #[error("a stored solid is {0} bytes, not 9")]
    Stored(usize),
}

impl Solid {
    /// The default: a `line` with no depth, the pressure-width rod.
    pub const ROD: Solid = Solid { kind: SolidKind::Line, depth: None };

    /// Validates a solid: a `filled` or `hole` needs a depth; a depth lies within
    /// [[`MIN_DEPTH`], [`MAX_DEPTH`]].
    pub fn new(kind: SolidKind, depth: Option<f64>) -> Result<Solid, SolidError> {
        match depth {
            None if kind != SolidKind::Line => Err(SolidError::NoDepth(kind)),
            Some(d) if !d.is_finite() => Err(SolidError::NonFinite(d)),
            Some(d) if !(MIN_DEPTH..=MAX_DEPTH).contains(&d) => Err(SolidError::DepthRange(d)),
            _ => Ok(Solid { kind, depth }),
        }
    }

    pub fn kind(&self) -> SolidKind {
        self.kind
    }

    pub fn depth(&self) -> Option<f64> {
        self.depth
    }

    /// Whether this is the default rod.
    pub fn is_rod(&self) -> bool {
        *self == Solid::ROD
    }

    /// The stored form, 9 bytes: the kind (0 line, 1 filled, 2 hole), then the depth as a
    /// little-endian `f64` (NaN for none), bit-exact.
    pub fn to_bytes(&self) -> [u8; 9] {
        let mut bytes = [0u8; 9];
        bytes[0] = match self.kind {
            SolidKind::Line => 0,
            SolidKind::Filled => 1,
            SolidKind::Hole => 2,
        };
        bytes[1..].copy_from_slice(&self.depth.unwrap_or(f64::NAN).to_le_bytes());
        bytes
    }

    /// Reads [`Solid::to_bytes`] back, validated.
    pub fn from_bytes(bytes: &[u8]) -> Result<Solid, SolidError> {
        let bytes: &[u8; 9] = bytes.try_into().map_err(|_| SolidError::Stored(bytes.len()))?;
        let kind = match bytes[0] {
            0 => SolidKind::Line,
            1 => SolidKind::Filled,
            2 => SolidKind::Hole,
            other => return Err(SolidError::UnknownKind(other.to_string())),
        };
        let depth = f64::from_le_bytes(bytes[1..].try_into().expect("8 bytes"));
        Solid::new(kind, (!depth.is_nan()).then_some(depth))
    }
}

impl std::fmt::Display for Solid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.depth {
            Some(depth) => write!(f, "{} {depth} px deep", self.kind),
            None => write!(f, "{}", self.kind),
        }
    }
}

/// How far apart a stroke's ends are, and how far they may be for it to count as closed
/// ([`CLOSURE_WIDTHS`] widths): `(gap, allowed)`, px.
pub fn closure_gap(outline: &crate::Outline) -> (f64, f64) {
    let (Some(first), Some(last)) = (outline.centres.first(), outline.centres.last()) else {
        return (0.0, 0.0);
    };
    let widths = outline.radii.first().unwrap_or(&0.0) + outline.radii.last().unwrap_or(&0.0);
    (first.distance(*last), CLOSURE_WIDTHS * widths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_solid_is_validated_and_kept_bit_for_bit() {
        assert_eq!(Solid::default(), Solid::ROD);
        assert_eq!(
            Solid::new(SolidKind::Filled, None),
            Err(SolidError::NoDepth(SolidKind::Filled))
        );
        assert_eq!(Solid::new(SolidKind::Hole, Some(-1.0)), Err(SolidError::DepthRange(-1.0)));
        assert_eq!(Solid::new(SolidKind::Line, Some(1e9)), Err(SolidError::DepthRange(1e9)));
        assert!(matches!(
            Solid::new(SolidKind::Line, Some(f64::NAN)),
            Err(SolidError::NonFinite(_))
        ));
        let solid = Solid::new(SolidKind::Filled, Some(0.1 + 0.2)).unwrap();
        assert_eq!(Solid::from_bytes(&solid.to_bytes()), Ok(solid));
        assert_eq!(Solid::from_bytes(&Solid::ROD.to_bytes()), Ok(Solid::ROD));
        let json = serde_json::to_string(&solid).unwrap();
        assert_eq!(json, r#"{"kind":"filled","depth":0.30000000000000004}"#);
        assert_eq!(serde_json::from_str::<Solid>(&json).unwrap(), solid);
        let error = serde_json::from_str::<Solid>(r#"{"kind":"hole","depth":null}"#).unwrap_err();
        assert!(error.to_string().contains("a hole solid needs a depth"), "{error}");
        let error = serde_json::from_str::<Solid>(r#"{"kind":"plate","depth":1}"#).unwrap_err();
        assert!(error.to_string().contains("unknown variant"), "{error}");
    }
}
