//! The region of the plane a solid covers (`solid.rs`), as polygons with holes: the stroke's
//! ink (its pressure-width outline `T_c`), or the region a closed stroke encloses united with
//! its ink. `i_overlay` does the polygon work (self-overlaps, unions, fill rules).
//!
//! **The fill rule is non-zero.** The region a stroke encloses is its centreline closed by the
//! segment from its last point to its first, filled where that closed path winds round a point
//! any number of times other than zero: both lobes of a figure eight fill (they wind +1 and -1),
//! and so does the middle of a loop drawn twice round or of a five-pointed star (which winds
//! twice), where even-odd would leave a hole. `docs/model-format.md` draws it.
//!
//! The ink is filled by the non-zero rule too: the closed outline runs forward along one side
//! and back along the other, so every piece of ink winds the same way round its points and a
//! stroke crossing itself stays solid where it crosses, while the inside of a closed loop of
//! ink (wound once each way) stays empty.

use glam::DVec2;
use i_overlay::core::fill_rule::FillRule;
use i_overlay::core::overlay_rule::OverlayRule;
use i_overlay::float::overlay::FloatOverlay;
use i_overlay::float::simplify::SimplifyShape;

use crate::lrpdp::{Outline, PIXEL_TOLERANCE};
use crate::mesh::{kept_outline, visible_centres};
use crate::solid::{SolidError, SolidKind, closure_gap};

/// One closed contour, not repeating its first point.
pub type Contour = Vec<[f64; 2]>;
/// One connected piece of a region: its outer contour (counter-clockwise) then its holes
/// (clockwise).
pub type Polygon = Vec<Contour>;

/// The region a solid of `kind` made from `outline` covers: the ink of a `line` and of an open
/// `hole`, the filled region of a `filled` and of a closed `hole`. An open stroke cannot be
/// filled ([`SolidError::Open`]).
pub fn solid_region(outline: &Outline, kind: SolidKind) -> Result<Vec<Polygon>, SolidError> {
    match kind {
        SolidKind::Line => Ok(ink_region(outline)),
        SolidKind::Filled => filled_region(outline),
        SolidKind::Hole => filled_region(outline).or_else(|_| Ok(ink_region(outline))),
    }
}

/// The stroke's ink: its closed outline `T_c` (of the centreline points a pixel shows), its
/// self-overlaps merged.
pub fn ink_region(outline: &Outline) -> Vec<Polygon> {
    if outline.is_empty() {
        return Vec::new();
    }
    let keep = visible_centres(outline, PIXEL_TOLERANCE, 0.0);
    vec![visible_ink(outline, &keep)].simplify_shape(FillRule::NonZero)
}

/// The region a closed stroke encloses united with its ink; refused for an open stroke, naming
/// how far apart its ends are.
pub fn filled_region(outline: &Outline) -> Result<Vec<Polygon>, SolidError> {
    let (gap, allowed) = closure_gap(outline);
    if gap > allowed {
        return Err(SolidError::Open { gap, allowed });
    }
    if outline.is_empty() {
        return Ok(Vec::new());
    }
    let keep = visible_centres(outline, PIXEL_TOLERANCE, 0.0);
    let enclosed: Contour = keep.iter().map(|&k| point(outline.centres[k])).collect();
    let ink = visible_ink(outline, &keep);
    Ok(FloatOverlay::with_subj_and_clip(&vec![enclosed], &vec![ink])
        .overlay(OverlayRule::Union, FillRule::NonZero))
}

/// The area of a region, px².
pub fn region_area(shapes: &[Polygon]) -> f64 {
    shapes.iter().flatten().map(|contour| signed_area(contour)).sum()
}

/// The signed area of a contour (positive counter-clockwise).
pub fn signed_area(contour: &[[f64; 2]]) -> f64 {
    let n = contour.len();
    (0..n)
        .map(|i| {
            let (a, b) = (contour[i], contour[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// The closed outline of the centreline points a pixel shows (what the rod's mesh keeps).
fn visible_ink(outline: &Outline, keep: &[usize]) -> Contour {
    kept_outline(outline, keep).closed().into_iter().map(point).collect()
}

fn point(p: DVec2) -> [f64; 2] {
    [p.x, p.y]
}
