//! Line charts as SVG (plotters): the one way the commands draw a plot (`eval`'s
//! rate-distortion curves, `load-report`'s throughput and latency against pens).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

pub use plotters::chart::SeriesLabelPosition;

/// One named line of a chart, drawn with a dot at each point.
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// A chart of several lines over a linear x axis from 0.
#[derive(Debug, Clone)]
pub struct LineChart<'a> {
    pub caption: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: &'a [Series],
    /// A logarithmic y axis (from 0.5), for latencies spanning decades.
    pub log_y: bool,
    /// Where the legend goes, so it hides no line.
    pub legend: SeriesLabelPosition,
    /// Width and height in px.
    pub size: (u32, u32),
}

/// Line colours, one per series in turn (colour-blind-safe first).
const COLOURS: [RGBColor; 11] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(120, 120, 120),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
];

impl LineChart<'_> {
    /// Writes the chart to `path` as SVG; the error names the file.
    pub fn write_svg(&self, path: &Path) -> anyhow::Result<()> {
        let root = SVGBackend::new(path, self.size).into_drawing_area();
        self.draw(&root).map_err(|e| anyhow::anyhow!("cannot draw {}: {e}", path.display()))
    }

    fn draw(
        &self,
        root: &DrawingArea<SVGBackend<'_>, Shift>,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let points = self.series.iter().flat_map(|s| s.points.iter());
        let x_max = points.clone().map(|p| p.0).fold(1.0, f64::max) * 1.05;
        let y_max = points.map(|p| p.1).fold(0.1, f64::max) * 1.1;
        root.fill(&WHITE)?;
        let mut builder = ChartBuilder::on(root);
        builder
            .caption(self.caption, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        if self.log_y {
            let mut chart = builder.build_cartesian_2d(0.0..x_max, (0.5..y_max).log_scale())?;
            chart.configure_mesh().x_desc(self.x_label).y_desc(self.y_label).draw()?;
            self.draw_lines(&mut chart)?;
        } else {
            let mut chart = builder.build_cartesian_2d(0.0..x_max, 0.0..y_max)?;
            chart.configure_mesh().x_desc(self.x_label).y_desc(self.y_label).draw()?;
            self.draw_lines(&mut chart)?;
        }
        root.present()?;
        Ok(())
    }

    fn draw_lines<'b, X, Y>(
        &self,
        chart: &mut ChartContext<'b, SVGBackend<'b>, Cartesian2d<X, Y>>,
    ) -> Result<(), Box<dyn std::error::Error>>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>,
    {
        for (k, series) in self.series.iter().enumerate() {
            if series.points.is_empty() {
                continue;
            }
            let colour = COLOURS[k % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(series.points.clone(), colour.stroke_width(2)))?
                .label(series.name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
            chart.draw_series(series.points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(self.legend.clone())
            .draw()?;
        Ok(())
    }
}
