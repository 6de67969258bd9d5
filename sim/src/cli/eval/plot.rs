//! Figures drawn with `plotters`, as SVG and PNG: step CDFs and scatter
//! plots, colour per terrain and line style (or marker) per lighting change,
//! ticks at round values, units on the axes, the legend beside the plot.
//!
//! Text of the PNG is drawn with DejaVu Sans embedded in the binary
//! (`sim/assets/fonts`), so no system font is needed; the SVG names the
//! `sans-serif` family.

use crate::error::{Error, Result};
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::OnceLock;

/// DejaVu Sans (Bitstream Vera licence, `sim/assets/fonts`).
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");
/// Family name the figures use.
const FAMILY: &str = "sans-serif";
/// Figure height, pixels; the width grows with the legend.
const HEIGHT: u32 = 540;
/// Width of the plot part, pixels.
const PLOT_W: u32 = 680;

/// Okabe–Ito colours (told apart with the common colour-vision
/// deficiencies), one per terrain.
/// Number of colours of the palette (groups past it change line style).
pub const PALETTE_LEN: usize = 6;

const PALETTE: [RGBColor; PALETTE_LEN] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(213, 94, 0),
];
/// A scatter's y axis is logarithmic when its positive values span more
/// than this ratio.
const LOG_SPAN: f64 = 30.0;
/// Dash and gap lengths (pixels) of the line styles; `(0, 0)` is solid.
const DASHES: [(u32, u32); 8] = [
    (0, 0),
    (9, 5),
    (2, 4),
    (16, 5),
    (5, 3),
    (12, 3),
    (3, 8),
    (24, 6),
];

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Style {
    /// Palette index (per terrain).
    pub color: usize,
    /// Line style (CDF) or marker (scatter) index (per lighting change).
    pub line: usize,
    /// A baseline relocalizer: thin lines, hollow markers.
    pub baseline: bool,
    /// Black crosses: failed trials.
    pub failed: bool,
}

impl Style {
    /// Colour `color`, line style `line`.
    pub fn new(color: usize, line: usize) -> Self {
        Self {
            color,
            line,
            baseline: false,
            failed: false,
        }
    }

    /// The same colour and line style, drawn as a baseline relocalizer's.
    pub fn as_baseline(self) -> Self {
        Self {
            baseline: true,
            ..self
        }
    }

    fn stroke(self) -> ShapeStyle {
        self.rgb().stroke_width(if self.baseline { 1 } else { 2 })
    }

    /// Failed trials.
    pub const FAILED: Self = Self {
        color: 0,
        line: 0,
        baseline: false,
        failed: true,
    };

    fn rgb(self) -> RGBColor {
        if self.failed {
            BLACK
        } else {
            PALETTE[self.color % PALETTE.len()]
        }
    }
}

/// What a figure draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Each series is the sorted values of a group, drawn as an empirical
    /// CDF (a step up of 1/n at each value), y in percent.
    Cdf,
    /// Each series is points (x, y).
    Scatter,
    /// Each series is rates (x, y in percent) joined in x order, y axis
    /// 0–100 % with a margin (a rate of 0 stays on the chart).
    Rate,
}

/// One series of a figure.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// How it is drawn.
    pub style: Style,
    /// CDF: the values (x only, y unused); scatter: the points.
    pub points: Vec<(f64, f64)>,
}

/// A figure, written as `<stem>.svg` and `<stem>.png`.
#[derive(Clone, Debug)]
pub struct Figure {
    /// File name without extension.
    pub stem: String,
    /// Title.
    pub title: String,
    /// X axis label, with its unit.
    pub x_label: String,
    /// Y axis label, with its unit.
    pub y_label: String,
    /// What it draws.
    pub kind: Kind,
    /// The series, in legend order.
    pub series: Vec<Series>,
}

impl Figure {
    /// The figure as an SVG document.
    ///
    /// # Errors
    /// A drawing failure.
    pub fn svg(&self) -> Result<String> {
        register_font()?;
        let mut s = String::new();
        {
            let root = SVGBackend::with_string(&mut s, (self.width(), HEIGHT)).into_drawing_area();
            self.draw(&root)
                .map_err(|e| Error::msg(format!("plot: {e}")))?;
            root.present()
                .map_err(|e| Error::msg(format!("plot: {e}")))?;
        }
        Ok(s)
    }

    /// The figure as a PNG image.
    ///
    /// # Errors
    /// A drawing or encoding failure.
    pub fn png(&self) -> Result<Vec<u8>> {
        register_font()?;
        let (w, h) = (self.width(), HEIGHT);
        let mut rgb = vec![255u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
            self.draw(&root)
                .map_err(|e| Error::msg(format!("plot: {e}")))?;
            root.present()
                .map_err(|e| Error::msg(format!("plot: {e}")))?;
        }
        let mut png = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut png),
            &rgb,
            w,
            h,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::msg(format!("plot: cannot encode PNG: {e}")))?;
        Ok(png)
    }

    /// Width: the plot and a legend wide enough for the longest label.
    fn width(&self) -> u32 {
        let longest = self
            .series
            .iter()
            .map(|s| s.name.chars().count())
            .max()
            .unwrap_or(0);
        PLOT_W + (longest as u32 * 8 + 70).clamp(160, 520)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let (plot, legend) = root.split_horizontally(PLOT_W);
        let (x, y, log_y) = self.ranges();
        let builder = || {
            let mut b = ChartBuilder::on(&plot);
            b.caption(&self.title, (FAMILY, 19))
                .margin(14)
                .x_label_area_size(52)
                .y_label_area_size(72);
            b
        };
        if log_y {
            let chart = builder().build_cartesian_2d(x.0..x.1, (y.0..y.1).log_scale())?;
            self.draw_chart(chart, x.1)?;
        } else {
            let chart = builder().build_cartesian_2d(x.0..x.1, y.0..y.1)?;
            self.draw_chart(chart, x.1)?;
        }
        self.draw_legend(&legend)
    }

    /// Axes, grid and series on a chart with a linear or a log y axis.
    fn draw_chart<DB, Y>(
        &self,
        mut chart: ChartContext<'_, DB, Cartesian2d<RangedCoordf64, Y>>,
        x_end: f64,
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>>
    where
        DB: DrawingBackend,
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        chart
            .configure_mesh()
            .x_desc(self.x_label.as_str())
            .y_desc(self.y_label.as_str())
            .x_labels(8)
            .y_labels(6)
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 15))
            .bold_line_style(RGBColor(220, 220, 220))
            .max_light_lines(0)
            .draw()?;
        for s in &self.series {
            match self.kind {
                Kind::Cdf => draw_path(&mut chart, &cdf_steps(&s.points, x_end), s.style)?,
                Kind::Scatter => draw_points(&mut chart, &s.points, s.style, false)?,
                Kind::Rate => {
                    draw_path(&mut chart, &s.points, s.style)?;
                    draw_points(&mut chart, &s.points, s.style, true)?;
                }
            }
        }
        Ok(())
    }

    /// The legend: a sample of each series' line or marker and its label.
    fn draw_legend<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        // 24 px a line, closer (and smaller) when that would not fit.
        let n = self.series.len().max(1) as i32;
        let step = (24).min((HEIGHT as i32 - 80) / n).max(10);
        let font = (FAMILY, (step - 9).clamp(9, 14)).into_font().color(&BLACK);
        for (i, s) in self.series.iter().enumerate() {
            let y = 62 + step * i as i32;
            match self.kind {
                Kind::Cdf => {
                    let (dash, gap) = DASHES[s.style.line % DASHES.len()];
                    let pts = [(6, y), (46, y)];
                    let st = s.style.stroke();
                    if dash == 0 {
                        area.draw(&PathElement::new(pts, st))?;
                    } else {
                        area.draw(&DashedPathElement::new(pts, dash, gap, st))?;
                    }
                }
                Kind::Scatter | Kind::Rate => draw_marker(area, (26, y), s.style)?,
            }
            area.draw(&Text::new(s.name.clone(), (54, y - step / 3), font.clone()))?;
        }
        Ok(())
    }

    /// Axis ranges: from 0 (or the smallest value below it) to a round value
    /// above the largest; a CDF's y axis is 0–100 % with a margin. A scatter
    /// whose positive y values span more than [`LOG_SPAN`] gets a log y axis
    /// (third value), from the power of ten at or below the smallest.
    fn ranges(&self) -> ((f64, f64), (f64, f64), bool) {
        let pts = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter())
                .filter(|p| p.0.is_finite() && p.1.is_finite())
        };
        let x_lo = pts().map(|p| p.0).fold(0.0, f64::min);
        let x_hi = pts().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        let y_hi = pts().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        let y_min_pos = pts()
            .map(|p| p.1)
            .filter(|&y| y > 0.0)
            .fold(f64::INFINITY, f64::min);
        // 4 % headroom, so no point sits on the frame.
        let x = (-round_up(-1.04 * x_lo), round_up(1.04 * x_hi));
        match self.kind {
            Kind::Cdf => (x, (-2.0, 102.0), false),
            Kind::Rate => (x, (-4.0, 104.0), false),
            Kind::Scatter if y_hi / y_min_pos > LOG_SPAN => {
                let lo = 10f64.powi(y_min_pos.log10().floor() as i32);
                (x, (lo, round_up(1.3 * y_hi)), true)
            }
            Kind::Scatter => (x, (0.0, round_up(1.04 * y_hi)), false),
        }
    }
}

/// The smallest of 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8 × 10ᵏ at or above
/// `v` (1 for nothing to show).
pub fn round_up(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return if v == 0.0 { 0.0 } else { 1.0 };
    }
    // m·10ᵏ, divided by 10⁻ᵏ below 1 so that 0.6 is 0.6.
    let k = v.log10().floor() as i32;
    let scale = |m: f64| {
        if k < 0 {
            m / 10f64.powi(-k)
        } else {
            m * 10f64.powi(k)
        }
    };
    [1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0]
        .into_iter()
        .map(scale)
        .find(|&c| c >= v * (1.0 - 1e-12))
        .unwrap_or_else(|| scale(10.0))
}

/// A tick label: the value with at most six decimals, trailing zeros dropped.
pub fn tick(v: f64) -> String {
    if v.abs() < 1e-9 {
        return "0".to_string();
    }
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// The vertices of the empirical CDF of `values` (x only), y in percent: a
/// rise of 100/n at each sorted value, flat in between and on to `x_end`.
pub fn cdf_steps(values: &[(f64, f64)], x_end: f64) -> Vec<(f64, f64)> {
    let mut v: Vec<f64> = values
        .iter()
        .map(|p| p.0)
        .filter(|x| x.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    let mut out = Vec::with_capacity(2 * v.len() + 1);
    for (i, &x) in v.iter().enumerate() {
        out.push((x, 100.0 * i as f64 / n));
        out.push((x, 100.0 * (i + 1) as f64 / n));
    }
    if let Some(&last) = v.last() {
        out.push((x_end.max(last), 100.0));
    }
    out
}

type Chart<'a, DB, Y> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, Y>>;

fn draw_path<DB: DrawingBackend, Y: Ranged<ValueType = f64>>(
    chart: &mut Chart<'_, DB, Y>,
    pts: &[(f64, f64)],
    style: Style,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (dash, gap) = DASHES[style.line % DASHES.len()];
    let st = style.stroke();
    if dash == 0 {
        chart.draw_series(LineSeries::new(pts.iter().copied(), st))?;
    } else {
        chart.draw_series(DashedLineSeries::new(pts.iter().copied(), dash, gap, st))?;
    }
    Ok(())
}

/// Markers at `pts`; a y of 0 or below only with `keep_zero` (a log axis has
/// no place for it).
fn draw_points<DB: DrawingBackend, Y: Ranged<ValueType = f64>>(
    chart: &mut Chart<'_, DB, Y>,
    pts: &[(f64, f64)],
    style: Style,
    keep_zero: bool,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let area = chart.plotting_area();
    let base = area.get_base_pixel();
    let pixels = area.strip_coord_spec();
    for p in pts
        .iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite() && (keep_zero || p.1 > 0.0))
    {
        let (x, y) = chart.backend_coord(p);
        draw_marker(&pixels, (x - base.0, y - base.1), style)?;
    }
    Ok(())
}

/// Outlines (closed) of the triangle, square and diamond markers, pixels
/// about the centre.
const OUTLINES: [[(i32, i32); 5]; 3] = [
    [(0, -7), (6, 4), (-6, 4), (0, -7), (0, -7)],
    [(-4, -4), (4, -4), (4, 4), (-4, 4), (-4, -4)],
    [(0, -6), (6, 0), (0, 6), (-6, 0), (0, -6)],
];

/// A marker at pixel `(x, y)` of `area`: per line index a circle, triangle,
/// square or diamond, filled for the first four indices and hollow for the
/// next four (and for a baseline relocalizer); a cross for failed trials.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    style: Style,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let c = style.rgb();
    if style.failed {
        return area.draw(&Cross::new((x, y), 5, c.stroke_width(2)));
    }
    let filled = style.line / 4 % 2 == 0 && !style.baseline;
    let st = if filled {
        c.mix(0.85).filled()
    } else {
        c.stroke_width(1)
    };
    let shape = style.line % 4;
    let Some(outline) = shape.checked_sub(1).and_then(|k| OUTLINES.get(k)) else {
        return area.draw(&Circle::new((x, y), 5, st));
    };
    let pts: Vec<(i32, i32)> = outline.iter().map(|(dx, dy)| (x + dx, y + dy)).collect();
    if filled {
        area.draw(&Polygon::new(pts, st))
    } else {
        area.draw(&PathElement::new(pts, st))
    }
}

/// Register the embedded font for the PNG text, once.
fn register_font() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::msg("plot: the embedded font cannot be read"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_values_ticks_and_cdf_steps() {
        assert_eq!(round_up(24.7), 25.0);
        assert_eq!(round_up(4.6), 5.0);
        assert_eq!(round_up(0.58), 0.6);
        assert_eq!(round_up(101.0), 120.0);
        assert_eq!(round_up(0.0), 0.0);
        assert_eq!(tick(0.30000000000000004), "0.3");
        assert_eq!(tick(20.0), "20");
        assert_eq!(tick(-0.0), "0");
        // Two values: up 50 % at each, then flat to the end of the axis.
        let s = cdf_steps(&[(7.0, 0.0), (3.0, 0.0)], 10.0);
        assert_eq!(
            s,
            [
                (3.0, 0.0),
                (3.0, 50.0),
                (7.0, 50.0),
                (7.0, 100.0),
                (10.0, 100.0)
            ]
        );
        assert!(cdf_steps(&[], 10.0).is_empty());
    }

    #[test]
    fn a_figure_draws_as_svg_and_png() {
        let fig = Figure {
            stem: "t".into(),
            title: "t".into(),
            x_label: "error (mm)".into(),
            y_label: "trials (%)".into(),
            kind: Kind::Cdf,
            series: vec![Series {
                name: "flagstone Δ3h".into(),
                style: Style::new(0, 1),
                points: vec![(1.0, 0.0), (2.0, 0.0)],
            }],
        };
        let svg = fig.svg().unwrap();
        assert!(svg.contains("flagstone Δ3h") && svg.contains("error (mm)"));
        let png = fig.png().unwrap();
        let img = image::load_from_memory(&png).unwrap();
        assert_eq!((img.width(), img.height()), (fig.width(), HEIGHT));
    }
}
