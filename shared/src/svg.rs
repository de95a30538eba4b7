//! An SVG picture of strokes and their simplifications, for looking at (not for exchange).
//!
//! Each stroke is drawn as its original polyline (thin, grey, with a small dot per sample) under
//! its simplified polyline (coloured) with a dot at every kept sample. The viewBox fits every
//! sample with a 5 % margin; line widths and dots scale with it, so a picture of tablet units looks
//! like one of px. Coordinates are used as they are, y pointing down as in SVG and CSS.

use std::fmt::Write;

use crate::model::Sample;

/// One stroke to draw: its original samples and the indices a simplification kept.
#[derive(Debug, Clone, Copy)]
pub struct SvgStroke<'a> {
    pub original: &'a [Sample],
    /// Indices into `original`, in order. Indices out of range are not drawn.
    pub kept: &'a [usize],
}

/// Colours of the simplified polylines, one per stroke in turn.
const PALETTE: [&str; 6] = ["#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf"];

/// The SVG document for one stroke and its simplification.
pub fn simplification_svg(original: &[Sample], kept: &[usize]) -> String {
    strokes_svg(&[SvgStroke { original, kept }])
}

/// The SVG document for several strokes and their simplifications.
pub fn strokes_svg(strokes: &[SvgStroke<'_>]) -> String {
    let (min_x, min_y, max_x, max_y) = strokes
        .iter()
        .flat_map(|stroke| stroke.original)
        .filter(|s| s.x.is_finite() && s.y.is_finite())
        .fold((f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY), |b, s| {
            (b.0.min(s.x), b.1.min(s.y), b.2.max(s.x), b.3.max(s.y))
        });
    let (x0, y0, width, height) = if min_x.is_finite() {
        let extent = (max_x - min_x).max(max_y - min_y).max(1e-9);
        let margin = 0.05 * extent;
        (min_x - margin, min_y - margin, max_x - min_x + 2.0 * margin, max_y - min_y + 2.0 * margin)
    } else {
        (0.0, 0.0, 1.0, 1.0)
    };
    let unit = width.max(height) / 500.0; // One px of an image 500 px across.
    let n_original: usize = strokes.iter().map(|stroke| stroke.original.len()).sum();
    let n_kept: usize = strokes.iter().map(|stroke| kept_samples(stroke).count()).sum();

    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="{} {} {} {}" width="{:.0}" height="{:.0}">"#,
        num(x0),
        num(y0),
        num(width),
        num(height),
        500.0 * width / width.max(height),
        500.0 * height / width.max(height),
    );
    let _ = writeln!(
        svg,
        "<title>{} stroke(s): {n_original} samples, {n_kept} kept</title>",
        strokes.len()
    );
    let _ = writeln!(
        svg,
        r#"<rect x="{}" y="{}" width="{}" height="{}" fill="white"/>"#,
        num(x0),
        num(y0),
        num(width),
        num(height)
    );
    for (stroke_idx, stroke) in strokes.iter().enumerate() {
        let colour = PALETTE[stroke_idx % PALETTE.len()];
        let _ = writeln!(svg, r#"<g id="stroke-{stroke_idx}">"#);
        polyline(&mut svg, stroke.original.iter(), "#999999", 0.8 * unit);
        dots(&mut svg, stroke.original.iter(), "#999999", 0.9 * unit);
        polyline(&mut svg, kept_samples(stroke), colour, 1.5 * unit);
        dots(&mut svg, kept_samples(stroke), colour, 2.5 * unit);
        svg.push_str("</g>\n");
    }
    svg.push_str("</svg>\n");
    svg
}

fn kept_samples<'a>(stroke: &SvgStroke<'a>) -> impl Iterator<Item = &'a Sample> + use<'a> {
    let original = stroke.original;
    stroke.kept.iter().filter_map(move |&i| original.get(i))
}

/// A number for SVG: finite, short.
fn num(v: f64) -> String {
    let v = if v.is_finite() { v } else { 0.0 };
    let text = format!("{v:.3}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0".to_string() } else { text.to_string() }
}

fn finite(s: &&Sample) -> bool {
    s.x.is_finite() && s.y.is_finite()
}

fn polyline<'a>(
    svg: &mut String,
    samples: impl Iterator<Item = &'a Sample>,
    colour: &str,
    width: f64,
) {
    let points: Vec<String> =
        samples.filter(finite).map(|s| format!("{},{}", num(s.x), num(s.y))).collect();
    if points.len() < 2 {
        return;
    }
    let _ = writeln!(
        svg,
        r#"<polyline fill="none" stroke="{colour}" stroke-width="{}" stroke-linejoin="round" points="{}"/>"#,
        num(width),
        points.join(" ")
    );
}

fn dots<'a>(
    svg: &mut String,
    samples: impl Iterator<Item = &'a Sample>,
    colour: &str,
    radius: f64,
) {
    let _ = write!(svg, r#"<g fill="{colour}">"#);
    for s in samples.filter(finite) {
        let _ = write!(svg, r#"<circle cx="{}" cy="{}" r="{}"/>"#, num(s.x), num(s.y), num(radius));
    }
    svg.push_str("</g>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(x: f64, y: f64) -> Sample {
        Sample::new(x, y, 0.0, 0.5)
    }

    #[test]
    // The viewBox fits the samples with a 5 % margin, and every sample and kept point is drawn.
    fn draws_both_polylines_and_fits_the_view() {
        let original = [s(0.0, 0.0), s(50.0, 100.0), s(100.0, 0.0)];
        let svg = simplification_svg(&original, &[0, 2]);
        assert!(
            svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"-5 -5 110 110\""),
            "{svg}"
        );
        assert!(svg.contains(r#"points="0,0 50,100 100,0""#), "{svg}");
        assert!(svg.contains(r#"points="0,0 100,0""#), "{svg}");
        assert_eq!(svg.matches("<circle").count(), 3 + 2);
        assert!(svg.contains("1 stroke(s): 3 samples, 2 kept"), "{svg}");
        assert!(svg.trim_end().ends_with("</svg>"));
    }

    #[test]
    // Several strokes get their own group and colour; empty input still makes a valid document.
    fn several_strokes_and_empty_input() {
        let a = [s(0.0, 0.0), s(1.0, 1.0)];
        let b = [s(2.0, 0.0), s(3.0, 1.0)];
        let svg = strokes_svg(&[
            SvgStroke { original: &a, kept: &[0, 1] },
            SvgStroke { original: &b, kept: &[0, 1, 9] },
        ]);
        assert!(svg.contains(r#"<g id="stroke-1">"#) && svg.contains(PALETTE[1]), "{svg}");
        assert!(svg.contains("2 stroke(s): 4 samples, 4 kept"), "{svg}");
        let empty = strokes_svg(&[]);
        assert!(empty.contains(r#"viewBox="0 0 1 1""#), "{empty}");
    }
}
