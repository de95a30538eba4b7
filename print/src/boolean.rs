//! The print's mesh booleans behind one small boundary: a closed solid made from a placed,
//! outward-wound triangle mesh, its convex hull, union and difference, and the triangles of
//! the result. The rest of the print knows nothing of the library that does them.
//!
//! The library is Manifold (`manifold-rs`: C++ built from the crate's vendored source with cmake
//! and ninja, which `scripts/native-deps.sh build` installs). The pure-Rust `boolmesh` was tried
//! in its place behind this boundary (issue 48): it passed every print test, but left
//! zero-volume shells in the 1,000-stroke board and took more memory and triangles
//! (`docs/fresh-machine.md`, "The print's boolean library").

use manifold_rs::{Manifold, Mesh};

/// A closed solid.
pub struct Solid(Manifold);

/// The triangles of a solid: positions and three indices per triangle, outward.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Triangles {
    pub positions: Vec<[f64; 3]>,
    pub indices: Vec<u32>,
}

impl Solid {
    /// The solid bounded by `positions` (x, y, z each) and `indices` (three a triangle, counter-
    /// clockwise seen from outside); `None` when they do not bound a closed manifold.
    pub fn from_mesh(positions: &[[f32; 3]], indices: &[u32]) -> Option<Solid> {
        let vertices: Vec<f32> = positions.iter().flatten().copied().collect();
        let manifold = Mesh::new(&vertices, indices).to_manifold();
        (!manifold.is_empty()).then_some(Solid(manifold))
    }

    /// Nothing.
    pub fn empty() -> Solid {
        Solid(Manifold::empty())
    }

    /// Its convex hull.
    pub fn hull(&self) -> Solid {
        Solid(self.0.hull())
    }

    /// What is in either.
    pub fn union(&self, other: &Solid) -> Solid {
        Solid(self.0.union(&other.0)).evaluated()
    }

    /// What is in `self` and not in `other`.
    pub fn difference(&self, other: &Solid) -> Solid {
        Solid(self.0.difference(&other.0)).evaluated()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    pub fn triangles(&self) -> Triangles {
        let mesh = self.0.to_mesh();
        let props = mesh.num_props() as usize;
        let positions = mesh
            .vertices()
            .chunks_exact(props)
            .map(|v| [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])])
            .collect();
        Triangles { positions, indices: mesh.indices() }
    }

    /// Manifold's booleans are lazy; each is evaluated at once (asking whether it is empty
    /// does) so that the caller's progress tracks the work.
    fn evaluated(self) -> Solid {
        let _ = self.0.is_empty();
        self
    }
}

impl std::fmt::Debug for Solid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Solid({} triangles)", self.triangles().indices.len() / 3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned box from `lo` to `hi`, wound outward.
    fn cube(lo: [f32; 3], hi: [f32; 3]) -> Solid {
        let p = |i: usize| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        };
        let positions: Vec<[f32; 3]> = (0..8).map(p).collect();
        #[rustfmt::skip]
        let indices = [
            0, 2, 1, 1, 2, 3, // z = lo
            4, 5, 6, 5, 7, 6, // z = hi
            0, 1, 4, 1, 5, 4, // y = lo
            2, 6, 3, 3, 6, 7, // y = hi
            0, 4, 2, 2, 4, 6, // x = lo
            1, 3, 5, 3, 7, 5, // x = hi
        ];
        Solid::from_mesh(&positions, &indices).expect("a cube is a closed manifold")
    }

    fn volume(t: &Triangles) -> f64 {
        let v = |i: u32| glam::DVec3::from(t.positions[i as usize]);
        t.indices.chunks_exact(3).map(|c| v(c[0]).dot(v(c[1]).cross(v(c[2])))).sum::<f64>() / 6.0
    }

    #[test]
    fn union_and_difference_of_two_overlapping_boxes_have_the_volumes_of_their_sets() {
        // Two unit cubes overlapping by half along x: the union is 1.5, the first less the
        // second 0.5; an open mesh is no solid; the empty solid changes nothing.
        let a = cube([0.0; 3], [1.0; 3]);
        let b = cube([0.5, 0.0, 0.0], [1.5, 1.0, 1.0]);
        assert!((volume(&a.union(&b).triangles()) - 1.5).abs() < 1e-6);
        assert!((volume(&a.difference(&b).triangles()) - 0.5).abs() < 1e-6);
        assert!((volume(&a.union(&Solid::empty()).triangles()) - 1.0).abs() < 1e-6);
        assert!(a.difference(&a).is_empty());
        let open = Solid::from_mesh(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[0, 1, 2]);
        assert!(open.is_none());
    }

    #[test]
    fn hull_fills_in_a_notch() {
        // An L of two boxes: its hull is the box's half of the square it spans, plus the notch.
        let l = cube([0.0; 3], [2.0, 1.0, 1.0]).union(&cube([0.0; 3], [1.0, 2.0, 1.0]));
        assert!((volume(&l.triangles()) - 3.0).abs() < 1e-6);
        assert!((volume(&l.hull().triangles()) - 3.5).abs() < 1e-6);
    }
}
