//! What an STL reader sees. STL has no indices: a reader joins triangles at corners with the same
//! `f32` position. Manifold's output is a closed manifold on its indices, but it computes in
//! `f64` and hands its vertices out as `f32`, so two of its vertices that lie closer than an
//! `f32` step (where two sheets of the union touch, an edge cut almost where another ends) can
//! come out at one position; an STL reader then joins what Manifold keeps apart and finds edges
//! with four triangles. So before the print is written every vertex is given a position of its
//! own (a repeated one moves by the least `f32` step, far below any printer's detail), and the
//! STL reader's joining gives back exactly Manifold's indexed mesh.

use std::collections::{HashMap, HashSet};

use crate::solid::PrintMesh;

/// `positions` with every repeated position moved by the least `f32` steps (along x, then y,
/// then z) to one that no other vertex has.
pub(crate) fn apart(mut positions: Vec<[f32; 3]>) -> Vec<[f32; 3]> {
    let mut taken: HashSet<[u32; 3]> = HashSet::with_capacity(positions.len());
    for p in &mut positions {
        let mut axis = 0;
        while !taken.insert(p.map(f32::to_bits)) {
            p[axis] = next_up(p[axis]);
            axis = (axis + 1) % 3;
        }
    }
    positions
}

/// The least `f32` above `x` (`f32::next_up`, which is newer than the workspace's Rust).
fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        x
    } else if x == 0.0 {
        f32::from_bits(1)
    } else if x > 0.0 {
        f32::from_bits(x.to_bits() + 1)
    } else {
        f32::from_bits(x.to_bits() - 1)
    }
}

impl PrintMesh {
    /// The directed edges that do not have exactly one opposite twin once corners at one
    /// position are joined, as an STL reader joins them: 0 for a closed, consistently wound
    /// surface.
    pub fn open_edges(&self) -> usize {
        let mut first: HashMap<[u32; 3], u32> = HashMap::with_capacity(self.positions.len());
        let joined: Vec<u32> = (0..self.positions.len() as u32)
            .map(|i| *first.entry(self.positions[i as usize].map(f32::to_bits)).or_insert(i))
            .collect();
        let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(self.indices.len());
        for triangle in self.triangles() {
            let [a, b, c] = triangle.map(|i| joined[i as usize]);
            for edge in [(a, b), (b, c), (c, a)] {
                *directed.entry(edge).or_default() += 1;
            }
        }
        directed
            .iter()
            .filter(|&(&(from, to), &count)| count != 1 || directed.get(&(to, from)) != Some(&1))
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two closed tetrahedra that touch at one point: vertices 3 and 4 are distinct but at one
    /// position, as Manifold leaves two sheets that touch.
    fn touching_tetrahedra() -> PrintMesh {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 2.0],
            [0.0, 1.0, 2.0],
            [0.0, 0.0, 2.0],
        ];
        let tetrahedron = |[a, b, c, d]: [u32; 4]| [a, c, b, a, b, d, b, c, d, c, a, d];
        let indices = [tetrahedron([0, 1, 2, 3]), tetrahedron([7, 6, 5, 4])].concat();
        PrintMesh { positions, indices }
    }

    #[test]
    fn every_vertex_gets_a_position_of_its_own_so_the_joined_mesh_stays_closed() {
        let mesh = touching_tetrahedra();
        // Joined at the one point, every edge still has its twin.
        assert_eq!(mesh.open_edges(), 0);
        // Vertex 7 moved onto vertex 1: the edge 1-3 of one and 7-4 of the other lie on one
        // line, and an STL reader joins them into an edge of four triangles.
        let mut pinched = mesh.clone();
        pinched.positions[7] = [1.0, 0.0, 0.0];
        assert!(pinched.open_edges() > 0);
        let apart = PrintMesh { positions: apart(pinched.positions.clone()), ..pinched.clone() };
        assert_eq!(apart.open_edges(), 0);
        // Only the repeats moved (4 and 7), by one f32 step.
        let moved: Vec<usize> =
            (0..8).filter(|&i| apart.positions[i] != pinched.positions[i]).collect();
        assert_eq!(moved, [4, 7]);
        assert_eq!(apart.positions[7][0], f32::from_bits(1.0f32.to_bits() + 1));
    }
}
