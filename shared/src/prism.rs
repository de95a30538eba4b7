//! A region of the plane (`region.rs`) extruded into a closed solid from `z = 0` to `z = depth`:
//! the mesh of every solid with a depth (`solid.rs`). Each connected shape's outer contour and
//! holes become side walls; its top and bottom are the shape triangulated by ear clipping
//! (`earcutr`) on the contours' own points, so the caps and the walls share every edge and the
//! mesh is closed.

use glam::DVec2;

use crate::mesh::StrokeMesh;
use crate::region::{Contour, Polygon, signed_area};

/// How the prism's vertices are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PrismVertices {
    /// One vertex per contour point and face (top, bottom): the index buffer is the topology
    /// (what the print and the closedness check take).
    Shared,
    /// The caps' vertices apart from the walls', so that a renderer shades the flat top and
    /// bottom flat and the walls round (what a GLB carries); closed by position.
    Flat,
}

/// The closed solid of `shapes` from `z = 0` to `z = depth`, wound outward. A shape the
/// triangulator cannot cut into triangles (a degenerate sliver) is left out, so the result is
/// closed whatever it is given.
pub fn prism_mesh(shapes: &[Polygon], depth: f64, vertices: PrismVertices) -> StrokeMesh {
    let mut mesh = StrokeMesh::default();
    for shape in shapes {
        let Some(caps) = triangulate(shape) else { continue };
        add_shape(&mut mesh, shape, &caps, depth, vertices);
    }
    mesh
}

/// The triangles of a shape's top face (indices into its contours' points in order),
/// counter-clockwise seen from above; `None` when ear clipping fails or misses part of it.
fn triangulate(shape: &Polygon) -> Option<Vec<usize>> {
    let mut coordinates = Vec::new();
    let mut holes = Vec::new();
    for (c, contour) in shape.iter().enumerate() {
        if c > 0 {
            holes.push(coordinates.len() / 2);
        }
        coordinates.extend(contour.iter().flatten());
    }
    let mut triangles = earcutr::earcut(&coordinates, &holes, 2).ok()?;
    let at = |i: usize| [coordinates[2 * i], coordinates[2 * i + 1]];
    let mut covered = 0.0;
    for t in triangles.chunks_exact_mut(3) {
        let area = signed_area(&[at(t[0]), at(t[1]), at(t[2])]);
        if area < 0.0 {
            t.swap(1, 2);
        }
        covered += area.abs();
    }
    let area: f64 = shape.iter().map(|c| signed_area(c)).sum();
    // Ear clipping that gives up part way covers less than the shape: a hole in the cap.
    ((covered - area).abs() <= 1e-6 * area.abs().max(1.0)).then_some(triangles)
}

fn add_shape(
    mesh: &mut StrokeMesh,
    shape: &Polygon,
    caps: &[usize],
    depth: f64,
    vertices: PrismVertices,
) {
    let points: Vec<[f64; 2]> = shape.iter().flatten().copied().collect();
    let n = points.len() as u32;
    let base = mesh.positions.len() as u32;
    let at = |p: [f64; 2], z: f64| [p[0] as f32, p[1] as f32, z as f32];
    let wall_normals = wall_normals(shape);

    // Top (base .. base + n) and bottom (base + n .. base + 2n); Flat adds the walls' own.
    for (p, normal) in points.iter().zip(&wall_normals) {
        mesh.positions.push(at(*p, depth));
        mesh.normals.push(match vertices {
            PrismVertices::Shared => *normal,
            PrismVertices::Flat => [0.0, 0.0, 1.0],
        });
    }
    for (p, normal) in points.iter().zip(&wall_normals) {
        mesh.positions.push(at(*p, 0.0));
        mesh.normals.push(match vertices {
            PrismVertices::Shared => *normal,
            PrismVertices::Flat => [0.0, 0.0, -1.0],
        });
    }
    let wall = match vertices {
        PrismVertices::Shared => base,
        PrismVertices::Flat => {
            for z in [depth, 0.0] {
                for (p, normal) in points.iter().zip(&wall_normals) {
                    mesh.positions.push(at(*p, z));
                    mesh.normals.push(*normal);
                }
            }
            base + 2 * n
        }
    };

    for t in caps.chunks_exact(3) {
        let [a, b, c] = [t[0] as u32, t[1] as u32, t[2] as u32];
        mesh.indices.extend([base + a, base + b, base + c]);
        mesh.indices.extend([base + n + a, base + n + c, base + n + b]);
    }
    let mut start = 0u32;
    for contour in shape {
        let len = contour.len() as u32;
        for i in 0..len {
            let (a, b) = (start + i, start + (i + 1) % len);
            let (top_a, top_b, bottom_a, bottom_b) =
                (wall + a, wall + b, wall + n + a, wall + n + b);
            mesh.indices.extend([bottom_a, bottom_b, top_b, bottom_a, top_b, top_a]);
        }
        start += len;
    }
}

/// The outward unit normal of the walls at each point (the mean of its two edges'), in the
/// order of the shape's points.
fn wall_normals(shape: &Polygon) -> Vec<[f32; 3]> {
    let edge_normal = |a: [f64; 2], b: [f64; 2]| {
        let d = DVec2::from(b) - DVec2::from(a);
        DVec2::new(d.y, -d.x).normalize_or_zero()
    };
    let mut normals = Vec::new();
    for contour in shape {
        let contour: &Contour = contour;
        let len = contour.len();
        for i in 0..len {
            let before = edge_normal(contour[(i + len - 1) % len], contour[i]);
            let after = edge_normal(contour[i], contour[(i + 1) % len]);
            let n = (before + after).normalize_or(after);
            normals.push([n.x as f32, n.y as f32, 0.0]);
        }
    }
    normals
}
