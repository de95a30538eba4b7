//! The model storm's placements: matrices, the planes people draw on, and the changes they make.

use penmesh::Placement;

pub(super) type Matrix = [f64; 16];

/// `a · b`, column-major.
pub(super) fn mul(a: &Matrix, b: &Matrix) -> Matrix {
    let mut out = [0.0; 16];
    for col in 0..4 {
        for row in 0..4 {
            out[col * 4 + row] = (0..4).map(|k| a[k * 4 + row] * b[col * 4 + k]).sum();
        }
    }
    out
}

pub(super) fn translation(x: f64, y: f64, z: f64) -> Matrix {
    let mut m = penmesh::IDENTITY_MATRIX;
    m[12..15].copy_from_slice(&[x, y, z]);
    m
}

/// A turn of `deg` about the world's x axis (`axis` 0) or z axis (`axis` 2).
pub(super) fn turn(axis: usize, deg: f64) -> Matrix {
    let (s, c) = deg.to_radians().sin_cos();
    let mut m = penmesh::IDENTITY_MATRIX;
    let (i, j) = if axis == 0 { (1, 2) } else { (0, 1) };
    m[i * 4 + i] = c;
    m[i * 4 + j] = s;
    m[j * 4 + i] = -s;
    m[j * 4 + j] = c;
    m
}

pub(super) fn scaling(k: f64) -> Matrix {
    let mut m = penmesh::IDENTITY_MATRIX;
    for i in 0..3 {
        m[i * 4 + i] = k;
    }
    m
}

pub(super) fn placement(m: Matrix) -> Placement {
    Placement::new(m).unwrap_or_else(|e| panic!("the test made a bad placement {m:?}: {e}"))
}

/// A placement compared bit for bit (`-0.0` is not `0.0`), shown as its matrix.
#[derive(Clone, Copy)]
pub(super) struct Exact(pub(super) Placement);

impl PartialEq for Exact {
    fn eq(&self, other: &Exact) -> bool {
        self.0.to_bytes() == other.0.to_bytes()
    }
}

impl std::fmt::Debug for Exact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.0.matrix())
    }
}

pub(super) fn bits(p: &Placement) -> Exact {
    Exact(*p)
}

/// The work plane client `i` draws on: stood up by its own angle, turned and moved off the
/// others'.
pub(super) fn plane(i: usize) -> Placement {
    let f = i as f64;
    let stood = mul(&turn(2, 23.0 * f), &turn(0, 30.0 + 7.0 * f));
    placement(mul(&translation(60.0 * f, -40.0 * f, 25.0 * f), &stood))
}

/// How a drawer changes a stroke's placement.
#[derive(Debug, Clone, Copy)]
pub(super) enum Change {
    Move,
    Turn,
    Scale,
    Mirror,
}

/// `current` changed by `change`, the drawer's `n`th change: each one different from every
/// placement before it.
pub(super) fn changed(current: &Placement, change: Change, n: usize) -> Placement {
    let f = n as f64;
    let m = current.matrix();
    let new = match change {
        Change::Move => mul(&translation(3.5 + f, -2.25 * f, 0.5 * f + 1.0), m),
        Change::Turn => mul(&translation(0.0, 0.0, 0.125 * f + 1.0), &mul(&turn(2, 15.0), m)),
        Change::Scale => {
            let k = if current.scale() > 1.5 { 0.8 } else { 1.25 };
            mul(&translation(0.0, 0.5 * f + 1.0, 0.0), &mul(&scaling(k), m))
        }
        // In the stroke's own plane, about its y axis: the determinant changes sign.
        Change::Mirror => mul(&translation(-0.75 * f - 1.0, 0.0, 0.0), &mul(m, &scaling_x(-1.0))),
    };
    placement(new)
}

pub(super) fn scaling_x(k: f64) -> Matrix {
    let mut m = penmesh::IDENTITY_MATRIX;
    m[0] = k;
    m
}
