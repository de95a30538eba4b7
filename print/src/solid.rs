//! The print: every stroke's direct closed solid (`penmesh::solid_mesh`, the same outline as the
//! stroke's mesh) placed by its matrix, united by Manifold into one closed manifold with no
//! overlapping shells, and scaled to millimetres so that the model's longest side is
//! [`PrintOptions::size_mm`]. Disjoint strokes stay separate bodies of the one mesh.
//!
//! The printable thickness is a radius floor in model units applied before meshing: the
//! thinnest dimension of a stroke's solid is its thickness, `2 * DEFAULT_THICKNESS * r`, so every
//! stroke's radius is raised to at least the world radius `w` that comes out as
//! `min_thickness_mm` after the final scale. Raising radii by at most `w` grows the model's
//! bounds by at most `w` on each side, so with `L0` the longest side of the unfloored bounds
//! (centres with their radii), `w = t * L0 / (c * size - 2 * t)` (`c` the thickness factor)
//! keeps `c * w * size / (L0 + 2 * w) >= t` whatever the floored bounds turn out to be.
//!
//! Manifold's booleans are robust on closed, consistently wound inputs that do not pass through
//! themselves, coplanar overlaps included. A stroke's solid can (a loop, a figure-eight, a bend
//! tighter than its radius), so each stroke is cut into pieces that do not (`crate::pieces`),
//! and the pieces are united like strokes. The solid leaves out detail finer than
//! [`PRINT_TOLERANCE_MM`]. Manifold's output is a closed manifold on its indices; an STL has
//! none, so every vertex is given its own `f32` position (`crate::apart`) and a reader that
//! joins corners by position gets the same mesh back.
//!
//! **Solids** (issue 51): a stroke with a depth is the prism of its region
//! (`penmesh::solid_region`, `penmesh::prism_mesh`: a wall of its ink, or a plate), embedded by
//! construction, so it is not cut into pieces. The print is the union of every `line` and
//! `filled` solid minus the union of every `hole` ([`unite`], then `crate::boolean`'s difference:
//! the two booleans the backend does). A hole reaches [`HOLE_MARGIN_MM`] beyond its faces, so that a hole as deep
//! as the plate it is drawn on goes through it rather than leaving a skin of zero thickness.

use glam::{DMat4, DVec3};
use penmesh::{
    Brush, DEFAULT_THICKNESS, KeptError, Outline, OutlineOptions, PIXEL_TOLERANCE, PrismVertices,
    Sample, SolidError, SolidKind, SolidOptions, StrokeMesh, fitted_outline, prism_mesh,
    solid_mesh, solid_region, visible_centres,
};

use crate::apart::apart;
use crate::boolean::{self, Triangles};
use crate::ordered::in_order;
use crate::pieces::pieces;

/// Default longest side of the print (mm).
pub const DEFAULT_SIZE_MM: f64 = 100.0;
/// Default smallest thickness of any part of the print (mm): a usual 0.4 mm nozzle lays two lines.
pub const DEFAULT_MIN_THICKNESS_MM: f64 = 0.8;
/// The print's detail (mm): the solid leaves out what lies closer than this to its outline
/// (an eighth of a usual 0.4 mm nozzle's line; never finer than the screen's 0.25 px).
pub const PRINT_TOLERANCE_MM: f64 = 0.05;
/// How far (mm) a hole reaches beyond its top and bottom faces: a hole as deep as its plate
/// goes through it.
pub const HOLE_MARGIN_MM: f64 = 0.05;
/// Largest accepted `size_mm`: beyond any printer's bed.
pub const MAX_SIZE_MM: f64 = 10_000.0;

/// The identity placement: the ground plane, every stroke's placement today.
pub const IDENTITY: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// The one change from penmesh's axes (x right, y down the page, z out of the board) to the
/// print's (a slicer's bed: X right, Y to the back, Z up), column-major: y is negated, so the
/// board seen from above reads as the page shows it (the top of the page at the back of the
/// bed) and a stroke on a standing plane stands up. It is a mirror of the numbers (not of the
/// model: penmesh's y runs down), so every solid's winding is flipped back with it. The scene's
/// GLB makes the same turn to glTF's Y up (`penmesh::scene_glb`).
pub const PRINT_AXES: [f64; 16] =
    [1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// One stroke to print: its drawn samples, the indices ACUTS kept of them (as the proxy stores
/// them; the outline is the stroke mesh's own, `penmesh::fitted_outline`), its brush, and its
/// placement (glTF's `node.matrix`: a column-major similarity from its plane to the session).
#[derive(Debug, Clone)]
pub struct PrintStroke {
    pub raw: Vec<Sample>,
    pub kept: Vec<usize>,
    pub brush: Brush,
    pub placement: [f64; 16],
    /// What the stroke becomes: the rod by default, a wall, a plate, or a hole.
    pub solid: penmesh::Solid,
}

/// How big the print is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrintOptions {
    /// The model's longest side (mm).
    pub size_mm: f64,
    /// Every part at least this thick (mm).
    pub min_thickness_mm: f64,
}

impl Default for PrintOptions {
    fn default() -> PrintOptions {
        PrintOptions { size_mm: DEFAULT_SIZE_MM, min_thickness_mm: DEFAULT_MIN_THICKNESS_MM }
    }
}

/// The united, closed mesh in millimetres, its lowest corner at the origin.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PrintMesh {
    pub positions: Vec<[f32; 3]>,
    /// Three indices per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl PrintMesh {
    pub fn triangles(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]])
    }

    /// The lowest and highest corner of the mesh's bounding box.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.positions {
            for axis in 0..3 {
                lo[axis] = lo[axis].min(f64::from(p[axis]));
                hi[axis] = hi[axis].max(f64::from(p[axis]));
            }
        }
        (lo, hi)
    }

    /// The enclosed volume (mm³): the signed sum of the origin's tetrahedra, in `f64`.
    pub fn volume(&self) -> f64 {
        let v = |i: u32| DVec3::from(self.positions[i as usize].map(f64::from));
        self.triangles().map(|[a, b, c]| v(a).dot(v(b).cross(v(c)))).sum::<f64>() / 6.0
    }
}

/// Why no print was made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrintError {
    #[error("nothing to print: no strokes")]
    NoStrokes,
    #[error("{name} = {value} mm is not accepted: {reason}")]
    BadOption { name: &'static str, value: f64, reason: String },
    #[error("stroke {index}: its placement {reason}")]
    BadPlacement { index: usize, reason: &'static str },
    #[error("stroke {index}: {error}")]
    Stroke { index: usize, error: KeptError },
    #[error("stroke {index}: {error}")]
    Solid { index: usize, error: SolidError },
    #[error("nothing to print: every stroke is a hole, and a hole cuts only what lies under it")]
    OnlyHoles,
    #[error("stroke {index}: its solid is not a closed manifold ({triangles} triangles)")]
    NotManifold { index: usize, triangles: usize },
    #[error("the strokes make no volume to print")]
    Empty,
}

/// Where the print is: `done` of `total` steps, `2n - 1` for `n` strokes: one per stroke meshed,
/// then `n - 1` shared out over the unions (a stroke that crosses itself is several pieces).
pub type Progress<'a> = &'a mut dyn FnMut(usize, usize);

/// The print of `strokes`: see the module docs.
pub fn print_mesh(
    strokes: &[PrintStroke],
    options: &PrintOptions,
    progress: Progress<'_>,
) -> Result<PrintMesh, PrintError> {
    options.validate()?;
    if strokes.is_empty() {
        return Err(PrintError::NoStrokes);
    }
    let placements = strokes
        .iter()
        .enumerate()
        .map(|(index, s)| placement(index, &s.placement))
        .collect::<Result<Vec<_>, _>>()?;
    let outline_options = OutlineOptions::default();
    let thickness = 2.0 * DEFAULT_THICKNESS.min(1.0);

    // Unfloored bounds: every centre with its radius, placed.
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    let stroke_bounds = |index: usize| {
        let (stroke, place) = (&strokes[index], &placements[index]);
        let outline = fitted_outline(&stroke.raw, &stroke.kept, &stroke.brush, &outline_options)
            .map_err(|error| PrintError::Stroke { index, error })?;
        let mut bounds = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let depth = stroke.solid.depth().unwrap_or(0.0);
        for (c, r) in outline.centres.iter().zip(&outline.radii) {
            for z in [0.0, depth] {
                let p = place.matrix.transform_point3(DVec3::new(c.x, c.y, z));
                bounds = (bounds.0.min(p - r * place.scale), bounds.1.max(p + r * place.scale));
            }
        }
        Ok(bounds)
    };
    in_order(strokes.len(), stroke_bounds, |_, bounds: Result<(DVec3, DVec3), PrintError>| {
        let (a, b) = bounds?;
        (lo, hi) = (lo.min(a), hi.max(b));
        Ok(())
    })?;
    let longest = (hi - lo).max_element();
    if !longest.is_finite() || longest <= 0.0 {
        return Err(PrintError::Empty);
    }
    let t = options.min_thickness_mm;
    let floor_world = t * longest / (thickness * options.size_mm - 2.0 * t);
    // At most this far (mm) from the stroke's exact outline: the same scale estimate, which the
    // floors only make coarser.
    let tolerance_world = PRINT_TOLERANCE_MM * longest / options.size_mm;

    let n = strokes.len();
    let total = 2 * n - 1;
    let mut solids = Vec::with_capacity(n);
    // Each stroke's pieces are meshed on the worker threads, made Manifolds here in order.
    let stroke_pieces = |index: usize| {
        let (stroke, place) = (&strokes[index], &placements[index]);
        let mut brush = stroke.brush;
        brush.min_radius = brush.min_radius.max(floor_world / place.scale);
        // The print's detail in the stroke's own units, never finer than the screen's.
        let tolerance = (tolerance_world / place.scale).max(PIXEL_TOLERANCE);
        let stroke_options = outline_options.cap_tolerance(tolerance);
        let outline = fitted_outline(&stroke.raw, &stroke.kept, &brush, &stroke_options)
            .map_err(|error| PrintError::Stroke { index, error })?;
        let Some(depth) = stroke.solid.depth() else {
            return Ok(piece_meshes(&outline, tolerance));
        };
        let region = solid_region(&outline, stroke.solid.kind())
            .map_err(|error| PrintError::Solid { index, error })?;
        if stroke.solid.kind() != SolidKind::Hole {
            let mesh = prism_mesh(&region, depth, PrismVertices::Shared);
            return Ok(vec![PieceMesh { mesh, hull: false }]);
        }
        let margin = HOLE_MARGIN_MM * longest / options.size_mm / place.scale;
        let mut mesh = prism_mesh(&region, depth + 2.0 * margin, PrismVertices::Shared);
        for p in &mut mesh.positions {
            p[2] -= margin as f32;
        }
        Ok(vec![PieceMesh { mesh, hull: false }])
    };
    let mut holes = Vec::new();
    in_order(n, stroke_pieces, |index, meshes: Result<Vec<PieceMesh>, PrintError>| {
        for piece in meshes? {
            let solid = placed_solid(index, &piece.mesh, &placements[index])?;
            let solid =
                if piece.hull { Placed { body: solid.body.hull(), ..solid } } else { solid };
            if strokes[index].solid.kind() == SolidKind::Hole {
                holes.push(solid);
            } else {
                solids.push(solid);
            }
        }
        progress(index + 1, total);
        Ok(())
    })?;
    if solids.is_empty() {
        return Err(PrintError::OnlyHoles);
    }
    // The booleans' share of the steps: `n - 1` whatever the number of pieces and holes.
    let booleans = solids.len() - 1 + holes.len();
    let mut done_count = 0;
    let mut reported = n;
    let mut step = || {
        done_count += 1;
        let done = n + done_count * (n - 1) / booleans.max(1);
        if done > reported {
            reported = done;
            progress(done, total);
        }
    };
    let united = unite(solids, &mut step);
    let united = if holes.is_empty() {
        united
    } else {
        let cut = unite(holes, &mut step);
        let result = united.difference(&cut);
        step();
        result
    };
    to_millimetres(&united.triangles(), options.size_mm)
}

impl PrintOptions {
    /// Refuses a size or thickness no print can have, naming it.
    pub fn validate(&self) -> Result<(), PrintError> {
        let PrintOptions { size_mm, min_thickness_mm } = *self;
        if !(size_mm.is_finite() && size_mm > 0.0 && size_mm <= MAX_SIZE_MM) {
            return Err(PrintError::BadOption {
                name: "size_mm",
                value: size_mm,
                reason: format!("it must be above 0 and at most {MAX_SIZE_MM}"),
            });
        }
        let most = size_mm * DEFAULT_THICKNESS.min(1.0) / 2.0;
        if !(min_thickness_mm.is_finite() && min_thickness_mm > 0.0 && min_thickness_mm < most) {
            return Err(PrintError::BadOption {
                name: "min_thickness_mm",
                value: min_thickness_mm,
                reason: format!("it must be above 0 and below {most} (a quarter of size_mm)"),
            });
        }
        Ok(())
    }
}

/// A stroke's placement followed by [`PRINT_AXES`]: from its plane to the print's axes.
struct Placement {
    matrix: DMat4,
    /// The similarity's uniform scale.
    scale: f64,
    mirrored: bool,
}

fn placement(index: usize, m: &[f64; 16]) -> Result<Placement, PrintError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(PrintError::BadPlacement { index, reason: "has a value that is not finite" });
    }
    let matrix = DMat4::from_cols_array(&PRINT_AXES) * DMat4::from_cols_array(m);
    let det = glam::DMat3::from_mat4(matrix).determinant();
    if det.abs() <= 1e-12 {
        return Err(PrintError::BadPlacement { index, reason: "is singular" });
    }
    Ok(Placement { matrix, scale: det.abs().cbrt(), mirrored: det < 0.0 })
}

/// One piece of a stroke's solid (`crate::pieces`), unplaced, and whether Manifold replaces it
/// by its convex hull.
struct PieceMesh {
    mesh: StrokeMesh,
    hull: bool,
}

/// The stroke's solid as meshes that each are embedded (`crate::pieces`): the solid itself when
/// it does not pass through itself.
fn piece_meshes(outline: &Outline, tolerance: f64) -> Vec<PieceMesh> {
    let options = SolidOptions::default();
    // The centreline points the solid keeps at this tolerance; the pieces are cut from those.
    let keep = visible_centres(outline, tolerance, options.thickness);
    let kept = kept_outline(outline, &keep);
    let exact = options.tolerance(0.0);
    pieces(&kept, tolerance)
        .iter()
        .map(|piece| PieceMesh { mesh: solid_mesh(&piece.outline, &exact), hull: piece.hull })
        .collect()
}

/// The outline with only the centreline points `keep` (increasing indices), caps unchanged.
fn kept_outline(outline: &Outline, keep: &[usize]) -> Outline {
    let pick = |values: &[glam::DVec2]| keep.iter().map(|&k| values[k]).collect();
    Outline {
        centres: pick(&outline.centres),
        radii: keep.iter().map(|&k| outline.radii[k]).collect(),
        normals: pick(&outline.normals),
        upper: pick(&outline.upper),
        lower: pick(&outline.lower),
        ..outline.clone()
    }
}

/// The placed solid; a mirror (a mirroring placement, or none: [`PRINT_AXES`] is one) turns the
/// triangles inside out, so their winding is flipped back.
fn placed_solid(index: usize, mesh: &StrokeMesh, place: &Placement) -> Result<Placed, PrintError> {
    let vertices: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| {
            let q = place.matrix.transform_point3(DVec3::from(p.map(f64::from)));
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    let mut indices = mesh.indices.clone();
    if place.mirrored {
        for t in indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
    }
    let triangles = indices.len() / 3;
    let body = boolean::Solid::from_mesh(&vertices, &indices)
        .ok_or(PrintError::NotManifold { index, triangles })?;
    let (lo, hi) = vertices.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), v| {
        let v = DVec3::from(v.map(f64::from));
        (lo.min(v), hi.max(v))
    });
    Ok(Placed { body, centre: (lo + hi) / 2.0 })
}

/// A placed solid and the centre of its bounds.
struct Placed {
    body: boolean::Solid,
    centre: DVec3,
}

/// Unites the solids as a balanced tree of compact regions: split at the median centre across
/// the longer side, each half united, then the two. Each union meets only its neighbours' faces
/// and has inputs of similar size. `step` is called after each union.
fn unite(mut solids: Vec<Placed>, step: &mut dyn FnMut()) -> boolean::Solid {
    if solids.len() <= 1 {
        return solids.pop().map_or_else(boolean::Solid::empty, |s| s.body);
    }
    let (lo, hi) = solids.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), s| {
        (lo.min(s.centre), hi.max(s.centre))
    });
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    solids.sort_by(|a, b| a.centre[axis].total_cmp(&b.centre[axis]));
    let right = solids.split_off(solids.len() / 2);
    let a = unite(solids, step);
    let b = unite(right, step);
    let united = a.union(&b);
    step();
    united
}

/// The united mesh scaled so its longest side is `size_mm`, its lowest corner moved to the
/// origin.
fn to_millimetres(mesh: &Triangles, size_mm: f64) -> Result<PrintMesh, PrintError> {
    let points: Vec<DVec3> = mesh.positions.iter().map(|&p| DVec3::from(p)).collect();
    let lo = points.iter().fold(DVec3::INFINITY, |a, &p| a.min(p));
    let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p));
    let longest = (hi - lo).max_element();
    if points.is_empty() || longest.is_nan() || longest <= 0.0 {
        return Err(PrintError::Empty);
    }
    let k = size_mm / longest;
    let positions = points
        .iter()
        .map(|&p| {
            let q = (p - lo) * k;
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    Ok(PrintMesh { positions: apart(positions), indices: mesh.indices.clone() })
}
