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
