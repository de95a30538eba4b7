//! Where a stroke's plane stands in the session's 3D space (`spec/system.md`, "The model in
//! 3D"): a similarity transform, written as glTF writes a node's `matrix`.
//!
//! A stroke's trajectory, its simplification and its mesh stay in the stroke's own plane
//! (z = 0 of its coordinates); its placement maps those coordinates into the session's. A
//! mesh never moves: its node does.
//!
//! The matrix is 16 `f64`, column-major (`matrix[12..15]` is the translation), exactly as
//! received: JSON (shortest round-trip text), the binary encoding (8 little-endian bytes each)
//! and both databases (a 128-byte blob, [`Placement::to_bytes`]) keep every bit.
//!
//! A placement is validated on construction, so the rest of the code never sees a bad one:
//! - every element finite;
//! - the last row (`matrix[3]`, `[7]`, `[11]`, `[15]`) exactly `0, 0, 0, 1` (an affine map);
//! - the upper-left 3×3 `A` a rotation (or a mirror) times a uniform scale `s`: `AᵀA = s²·I`
//!   within [`SIMILARITY_TOLERANCE`], relative to `s²`;
//! - `s` within [[`MIN_SCALE`], [`MAX_SCALE`]];
//! - each element of the translation within ±[`MAX_TRANSLATION`].
//!
//! A stored placement ([`Placement::from_bytes`]) is read with every check but the last, so
//! that one stored before the translation had a bound still reads; what uses a placement's
//! place (the export) asks [`Placement::check_translation`] and refuses it by name.
//!
//! The identity is the default: the board, z = 0, where every stroke stored before protocol
//! version 5 and every stroke of an older client lies.

use serde::{Deserialize, Serialize};

/// Largest deviation of `AᵀA` from `s²·I`, relative to `s²`, that still counts as a
/// similarity. A matrix stored as `f32` (a glTF file, a `Float32Array`) is off by some 10⁻⁷
/// relative, a composition of a few rotations in `f64` by 10⁻¹⁵; a shear or a non-uniform
/// scale of 0.0001 % is refused.
pub const SIMILARITY_TOLERANCE: f64 = 1e-6;
/// Smallest uniform scale of a placement.
pub const MIN_SCALE: f64 = 1e-3;
/// Largest uniform scale of a placement.
pub const MAX_SCALE: f64 = 1e3;
/// Largest translation of a placement along each axis, in px: the largest sample coordinate
/// (`MAX_COORDINATE`, 10⁶) times the largest scale, so anything a stroke can reach by its own
/// coordinates a placement can too. Far past any real model, and far inside what `f64` keeps
/// to the sample grid (1/16 px up to 2⁴⁹) and what a scene or a print can hold beside strokes
/// of a few px (1e39 made every print fail; 1e20 shrank the others to nothing in a GLB).
pub const MAX_TRANSLATION: f64 = crate::model::MAX_COORDINATE * MAX_SCALE;

/// The identity matrix, column-major.
pub const IDENTITY_MATRIX: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// A stroke's placement: a validated similarity transform (rotation, translation, uniform
/// scale, optionally a mirror), glTF `node.matrix` order. JSON: `{"matrix": [16 numbers]}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(try_from = "UncheckedPlacement")]
pub struct Placement {
    /// 16 numbers, column-major, as glTF's `node.matrix`; the translation is elements 12–14.
    #[schema(value_type = Vec<f64>, min_items = 16, max_items = 16)]
    matrix: [f64; 16],
}

/// A placement as it arrives, before validation.
#[derive(Deserialize)]
struct UncheckedPlacement {
    matrix: [f64; 16],
}

impl TryFrom<UncheckedPlacement> for Placement {
    type Error = PlacementError;
    fn try_from(unchecked: UncheckedPlacement) -> Result<Placement, PlacementError> {
        Placement::new(unchecked.matrix)
    }
}

/// Why a matrix is not a placement. Each names what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlacementError {
    #[error("matrix[{index}] is not a finite number ({value})")]
    NonFinite { index: usize, value: f64 },
    #[error(
        "matrix[{index}] = {value}: the last row of the matrix (elements 3, 7, 11, 15, \
         column-major) must be 0, 0, 0, 1"
    )]
    NotAffine { index: usize, value: f64 },
    #[error(
        "the matrix is not a similarity (rotation, uniform scale, translation, mirror): its \
         axes' lengths and angles are off by {deviation:e} relative to the scale, more than \
         {SIMILARITY_TOLERANCE:e} (a shear or a non-uniform scale)"
    )]
    NotSimilarity { deviation: f64 },
    #[error("the matrix scales by {scale}, outside [{MIN_SCALE}, {MAX_SCALE}]")]
    Scale { scale: f64 },
    #[error(
        "matrix[{index}] = {value:e}: a translation (elements 12, 13, 14) is at most \
         {MAX_TRANSLATION:e} px along each axis"
    )]
    Translation { index: usize, value: f64 },
    #[error("a stored placement is {0} bytes, not 128")]
    Stored(usize),
}

impl Placement {
    /// The identity: the stroke's plane is the board, z = 0.
    pub const IDENTITY: Placement = Placement { matrix: IDENTITY_MATRIX };

    /// Validates `matrix` (column-major) as a placement.
    pub fn new(matrix: [f64; 16]) -> Result<Placement, PlacementError> {
        let placement = Placement::similarity(matrix)?;
        placement.check_translation()?;
        Ok(placement)
    }

    /// Whether its translation is within ±[`MAX_TRANSLATION`] along each axis.
    pub fn check_translation(&self) -> Result<(), PlacementError> {
        match (12..15).find(|&i| self.matrix[i].abs() > MAX_TRANSLATION) {
            Some(index) => Err(PlacementError::Translation { index, value: self.matrix[index] }),
            None => Ok(()),
        }
    }

    /// Every check of [`Placement::new`] but the translation's bound.
    fn similarity(matrix: [f64; 16]) -> Result<Placement, PlacementError> {
        if let Some((index, &value)) = matrix.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(PlacementError::NonFinite { index, value });
        }
        for (index, want) in [(3, 0.0), (7, 0.0), (11, 0.0), (15, 1.0)] {
            if matrix[index] != want {
                return Err(PlacementError::NotAffine { index, value: matrix[index] });
            }
        }
        let column = |c: usize| [matrix[4 * c], matrix[4 * c + 1], matrix[4 * c + 2]];
        let columns = [column(0), column(1), column(2)];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let s2 = (0..3).map(|i| dot(columns[i], columns[i])).sum::<f64>() / 3.0;
        let scale = s2.sqrt();
        if !(MIN_SCALE..=MAX_SCALE).contains(&scale) {
            return Err(PlacementError::Scale { scale });
        }
        let mut deviation = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { s2 } else { 0.0 };
                deviation = deviation.max((dot(columns[i], columns[j]) - want).abs() / s2);
            }
        }
        if deviation > SIMILARITY_TOLERANCE {
            return Err(PlacementError::NotSimilarity { deviation });
        }
        Ok(Placement { matrix })
    }

    /// The 16 numbers, column-major.
    pub fn matrix(&self) -> &[f64; 16] {
        &self.matrix
    }

    /// Whether this is the identity, bit for bit (`-0.0` is not `0.0`).
    pub fn is_identity(&self) -> bool {
        self.to_bytes() == Placement::IDENTITY.to_bytes()
    }

    /// The uniform scale `s`.
    pub fn scale(&self) -> f64 {
        self.determinant().abs().cbrt()
    }

    /// The determinant of the upper-left 3×3: negative for a mirror.
    pub fn determinant(&self) -> f64 {
        let m = &self.matrix;
        m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2])
            + m[8] * (m[1] * m[6] - m[5] * m[2])
    }

    /// Whether it mirrors (a negative determinant): a mesh placed so must flip its winding to
    /// stay outward.
    pub fn is_mirror(&self) -> bool {
        self.determinant() < 0.0
    }

    /// Maps a point of the stroke's plane coordinates into the session's.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.matrix;
        [
            m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
            m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
            m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14],
        ]
    }

    /// The stored form: 16 little-endian `f64`, 128 bytes, bit-exact.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.matrix.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    /// Reads the stored form ([`Placement::to_bytes`]), validating it again, all but the
    /// translation's bound (a placement stored before it still reads).
    pub fn from_bytes(bytes: &[u8]) -> Result<Placement, PlacementError> {
        if bytes.len() != 128 {
            return Err(PlacementError::Stored(bytes.len()));
        }
        let mut matrix = [0.0; 16];
        for (value, chunk) in matrix.iter_mut().zip(bytes.chunks_exact(8)) {
            *value = f64::from_le_bytes(chunk.try_into().expect("chunks of 8"));
        }
        Placement::similarity(matrix)
    }

    /// Reads `m0,m1,…,m15` (the native client's `--placement`).
    pub fn parse_list(text: &str) -> Result<Placement, String> {
        let values: Vec<f64> = text
            .split(',')
            .enumerate()
            .map(|(i, v)| {
                v.trim().parse::<f64>().map_err(|e| format!("element {i} ({:?}): {e}", v.trim()))
            })
            .collect::<Result<_, _>>()?;
        let matrix: [f64; 16] = values
            .try_into()
            .map_err(|v: Vec<f64>| format!("{} numbers; a placement has 16", v.len()))?;
        Placement::new(matrix).map_err(|e| e.to_string())
    }
}

impl Default for Placement {
    fn default() -> Placement {
        Placement::IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotation by `angle` about z, scaled by `s`, translated by `t`, mirrored in x when asked.
    fn similarity(angle: f64, s: f64, t: [f64; 3], mirror: bool) -> [f64; 16] {
        let (sin, cos) = angle.sin_cos();
        let mx = if mirror { -1.0 } else { 1.0 };
        [
            mx * s * cos,
            mx * s * sin,
            0.0,
            0.0,
            -s * sin,
            s * cos,
            0.0,
            0.0,
            0.0,
            0.0,
            s,
            0.0,
            t[0],
            t[1],
            t[2],
            1.0,
        ]
    }

    // Rotations, scales at the bounds, translations and mirrors are placements.
    #[test]
    fn similarities_are_accepted() {
        for (angle, s, mirror) in [(0.0, 1.0, false), (0.7, 1e-3, false), (2.0, 1e3, true)] {
            let p = Placement::new(similarity(angle, s, [5.0, -3.0, 1e4], mirror)).unwrap();
            assert_eq!(p.is_mirror(), mirror);
            assert!((p.scale() - s).abs() <= 1e-9 * s);
        }
        // A standing plane: the board turned 90° about x.
        let standing =
            [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let p = Placement::new(standing).unwrap();
        assert_eq!(p.apply([2.0, 3.0, 0.0]), [2.0, 0.0, 3.0]);
        assert!(Placement::default().is_identity());
    }

    // Each kind of bad matrix is refused with an error that names what is wrong.
    #[test]
    fn bad_matrices_are_refused_naming_the_fault() {
        let mut nan = IDENTITY_MATRIX;
        nan[5] = f64::NAN;
        let mut projective = IDENTITY_MATRIX;
        projective[3] = 0.5;
        let mut shear = IDENTITY_MATRIX;
        shear[4] = 0.1;
        let mut stretch = IDENTITY_MATRIX;
        stretch[0] = 2.0;
        let cases = [
            (nan, "matrix[5] is not a finite number"),
            (projective, "matrix[3] = 0.5: the last row"),
            (shear, "not a similarity"),
            (stretch, "not a similarity"),
            (similarity(0.3, 2000.0, [0.0; 3], false), "scales by 2000"),
            (similarity(0.3, 1e-4, [0.0; 3], false), "outside [0.001, 1000]"),
            ([0.0; 16], "last row"),
        ];
        for (matrix, text) in cases {
            let err = Placement::new(matrix).unwrap_err().to_string();
            assert!(err.contains(text), "{err} (wanted {text:?})");
        }
        let mut zero = [0.0; 16];
        zero[15] = 1.0;
        assert!(Placement::new(zero).unwrap_err().to_string().contains("scales by 0"));
    }

    // A translation is bounded on every axis, either sign, at MAX_TRANSLATION exactly; a
    // stored one past it still reads, and says what is wrong when asked.
    #[test]
    fn a_translation_past_its_bound_is_refused_but_a_stored_one_reads() {
        for index in 12..15 {
            for sign in [1.0, -1.0] {
                let mut m = IDENTITY_MATRIX;
                m[index] = sign * MAX_TRANSLATION;
                Placement::new(m).unwrap();
                m[index] = sign * 1e39;
                let err = Placement::new(m).unwrap_err().to_string();
                let want = format!("matrix[{index}] = {:e}: a translation", sign * 1e39);
                assert!(err.contains(&want) && err.contains("at most 1e9 px"), "{err}");
            }
        }
        let mut m = IDENTITY_MATRIX;
        m[13] = 1e20;
        let stored: Vec<u8> = m.iter().flat_map(|v| v.to_le_bytes()).collect();
        let read = Placement::from_bytes(&stored).unwrap();
        let err = read.check_translation().unwrap_err().to_string();
        assert!(err.contains("matrix[13] = 1e20"), "{err}");
        let json = r#"{"matrix":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,1e39,1]}"#;
        let err = serde_json::from_str::<Placement>(json).unwrap_err().to_string();
        assert!(err.contains("matrix[14] = 1e39"), "{err}");
    }

    // JSON, the stored bytes and the parser keep every bit; JSON refuses a bad matrix.
    #[test]
    fn placements_round_trip_bit_exactly() {
        let p =
            Placement::new(similarity(0.1 + 0.2, 1.0 / 3.0, [0.1, 1e-300, -7.5], true)).unwrap();
        let json = serde_json::to_string(&p).unwrap();
        assert!(json.starts_with("{\"matrix\":["), "{json}");
        let back: Placement = serde_json::from_str(&json).unwrap();
        assert_eq!(back.to_bytes(), p.to_bytes());
        assert_eq!(Placement::from_bytes(&p.to_bytes()).unwrap().to_bytes(), p.to_bytes());
        let list: Vec<String> = p.matrix().iter().map(|v| format!("{v:?}")).collect();
        assert_eq!(Placement::parse_list(&list.join(",")).unwrap().to_bytes(), p.to_bytes());
        let err =
            serde_json::from_str::<Placement>(r#"{"matrix":[2,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]}"#)
                .unwrap_err()
                .to_string();
        assert!(err.contains("not a similarity"), "{err}");
        assert!(Placement::parse_list("1,0,0").unwrap_err().contains("3 numbers"));
        assert!(Placement::from_bytes(&[0; 12]).is_err());
    }
}
