//! SVG plots of trajectories, object tracks, speeds and errors, drawn with
//! plotters' SVG backend (no font feature: the backend writes `<text>`
//! elements and leaves glyphs to the viewer).
//!
//! Every data series is drawn as one `<polyline>` of stroke width
//! `SERIES_STROKE_PX` (axes and ticks are 1 px) and its legend marker is a
//! filled rectangle, so a series is easy to find in the file. A path
//! coloured by a value ([`ColouredPath`]) is drawn segment by segment, each
//! in the colour of its mean value on a [`ColourScale`], whose colours the
//! legend lists.

use super::ReportError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Canvas size in pixels.
pub const CANVAS_PX: (u32, u32) = (900, 700);
/// Stroke width of data series (axes and mesh are thinner).
pub const SERIES_STROKE_PX: u32 = 2;
const MARKER_RADIUS_PX: i32 = 3;
const MARGIN_PX: u32 = 15;
const X_LABEL_AREA_PX: u32 = 45;
const Y_LABEL_AREA_PX: u32 = 70;
const CAPTION_FONT_PX: u32 = 22;
const LABEL_FONT_PX: u32 = 15;

/// Colours for series without their own (Tableau 10, minus grey which is kept
/// for ground truth).
const PALETTE: [(u8, u8, u8); 9] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (188, 189, 34),
    (23, 190, 207),
];

/// Ground truth is black so estimates stand out against it.
pub const TRUTH_RGB: (u8, u8, u8) = (0, 0, 0);

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    /// A line through the points.
    Line,
    /// A marker per point.
    Markers,
    /// Both.
    LineMarkers,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
/// How a series looks.
pub struct Style {
    /// Line, markers or both.
    pub kind: LineKind,
    /// `None` picks the next palette colour.
    pub rgb: Option<(u8, u8, u8)>,
}

impl Default for Style {
    fn default() -> Style {
        Style {
            kind: LineKind::Line,
            rgb: None,
        }
    }
}

/// One labelled series of (x, y) points, e.g. (x_m, y_m) of a trajectory in
/// the world frame or (t_s, speed_mps).
#[derive(Debug, Clone, PartialEq)]
pub struct Series2D {
    /// Legend label.
    pub label: String,
    /// The points, in drawing order.
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub style: Style,
}

impl Series2D {
    /// A line in the next palette colour.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Series2D {
        Series2D {
            label: label.into(),
            points,
            style: Style::default(),
        }
    }

    /// A black line, for ground truth.
    pub fn truth(label: impl Into<String>, points: Vec<(f64, f64)>) -> Series2D {
        Series2D::line(label, points).with_rgb(TRUTH_RGB)
    }

    /// The same series in a fixed colour.
    pub fn with_rgb(mut self, rgb: (u8, u8, u8)) -> Series2D {
        self.style.rgb = Some(rgb);
        self
    }

    /// The same series drawn as `kind`.
    pub fn with_kind(mut self, kind: LineKind) -> Series2D {
        self.style.kind = kind;
        self
    }
}

/// A path whose points carry a value drawn as colour: (x, y, value), e.g.
/// (x_m, y_m, translation error m) of an ego trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct ColouredPath {
    /// What the path is (named in the legend's caption).
    pub label: String,
    /// The points, in drawing order.
    pub points: Vec<(f64, f64, f64)>,
}

/// Maps values in [`lo`, `hi`] to colours (dark blue to yellow, as viridis);
/// values outside are clamped.
///
/// [`lo`]: ColourScale::lo
/// [`hi`]: ColourScale::hi
#[derive(Debug, Clone, PartialEq)]
pub struct ColourScale {
    /// The value drawn darkest.
    pub lo: f64,
    /// The value drawn brightest.
    pub hi: f64,
    /// The value's name and unit, e.g. "translation error \[m\]".
    pub desc: String,
}

/// Viridis at 0, 1/4, 1/2, 3/4 and 1.
const RAMP: [(u8, u8, u8); 5] = [
    (68, 1, 84),
    (59, 82, 139),
    (33, 145, 140),
    (94, 201, 98),
    (253, 231, 37),
];

/// Legend swatches of a colour scale.
const SCALE_SWATCHES: usize = 5;

/// Stroke width of a coloured path (wider than a series: its colour is data).
const COLOURED_STROKE_PX: u32 = 4;

impl ColourScale {
    /// The colour of `value` (linear between the ramp's colours).
    pub fn rgb(&self, value: f64) -> (u8, u8, u8) {
        let span = self.hi - self.lo;
        let f = if span > 0.0 {
            ((value - self.lo) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let x = f * (RAMP.len() - 1) as f64;
        let i = (x.floor() as usize).min(RAMP.len() - 2);
        let r = x - i as f64;
        let mix = |a: u8, b: u8| (f64::from(a) + r * (f64::from(b) - f64::from(a))).round() as u8;
        let (a, b) = (RAMP[i], RAMP[i + 1]);
        (mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
    }
}

/// Data bounds: (x_min, x_max, y_min, y_max).
type Bounds = (f64, f64, f64, f64);

/// Checks every series is non-empty and finite; returns the data bounds.
fn validate(path: &Path, series: &[Series2D]) -> Result<Bounds, ReportError> {
    if series.is_empty() {
        return Err(ReportError::NoSeries {
            path: path.to_path_buf(),
        });
    }
    let mut b = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for s in series {
        if s.points.is_empty() {
            return Err(ReportError::EmptySeries {
                path: path.to_path_buf(),
                label: s.label.clone(),
            });
        }
        for (index, &(x, y)) in s.points.iter().enumerate() {
            if !x.is_finite() || !y.is_finite() {
                return Err(ReportError::NonFinite {
                    path: path.to_path_buf(),
                    label: s.label.clone(),
                    index,
                    x,
                    y,
                });
            }
            b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
        }
    }
    // Spans must be finite too, or plotters' coordinate maps overflow.
    if !(b.1 - b.0).is_finite() || !(b.3 - b.2).is_finite() {
        return Err(ReportError::Plot {
            path: path.to_path_buf(),
            message: format!(
                "data range too large to plot: x {:e}..{:e}, y {:e}..{:e}",
                b.0, b.1, b.2, b.3
            ),
        });
    }
    Ok(b)
}

/// Widens [lo, hi] by 5 % per side; a zero span gets ±1 so a constant series
/// (a parked object, zero error) still has an axis.
fn padded(lo: f64, hi: f64) -> (f64, f64) {
    let span = hi - lo;
    if span <= 0.0 {
        let pad = 1.0_f64.max(lo.abs() * 0.05);
        (lo - pad, hi + pad)
    } else {
        (lo - 0.05 * span, hi + 0.05 * span)
    }
}

/// Expands the padded ranges so one metre spans the same number of pixels on
/// both axes of a `w_px` × `h_px` plotting area (a top view must not distort
/// turns).
fn equal_scale_ranges(b: Bounds, w_px: u32, h_px: u32) -> ((f64, f64), (f64, f64)) {
    let (x0, x1) = padded(b.0, b.1);
    let (y0, y1) = padded(b.2, b.3);
    let (w, h) = (f64::from(w_px.max(1)), f64::from(h_px.max(1)));
    let m_per_px = ((x1 - x0) / w).max((y1 - y0) / h);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (hx, hy) = (0.5 * m_per_px * w, 0.5 * m_per_px * h);
    ((cx - hx, cx + hx), (cy - hy, cy + hy))
}

fn plot_err<E: std::error::Error + Send + Sync>(
    path: &Path,
) -> impl Fn(DrawingAreaErrorKind<E>) -> ReportError + '_ {
    move |e| ReportError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Builds the chart frame with fixed margins, so the plotting area's pixel size
/// does not depend on the data ranges.
fn chart_builder<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, Shift>,
    title: &str,
) -> ChartBuilder<'a, 'b, SVGBackend<'b>> {
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(title, ("sans-serif", CAPTION_FONT_PX))
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABEL_AREA_PX)
        .y_label_area_size(Y_LABEL_AREA_PX);
    builder
}

/// Pixel size of the plotting area of a chart titled `title` (a throw-away
/// layout pass on an in-memory canvas).
fn plotting_area_px(path: &Path, title: &str) -> Result<(u32, u32), ReportError> {
    let mut scratch = String::new();
    let root = SVGBackend::with_string(&mut scratch, CANVAS_PX).into_drawing_area();
    let chart = chart_builder(&root, title)
        .build_cartesian_2d(0.0..1.0, 0.0..1.0)
        .map_err(plot_err(path))?;
    Ok(chart.plotting_area().dim_in_pixel())
}

/// Draws `series` into an SVG string. `equal_scale` makes one x unit as long
/// as one y unit on screen.
fn render(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series2D],
    coloured: Option<(&ColouredPath, &ColourScale)>,
    equal_scale: bool,
) -> Result<String, ReportError> {
    // the coloured path's positions count for the bounds; its values and
    // scale are checked apart (they are no coordinates)
    let mut checked = series.to_vec();
    if let Some((c, scale)) = coloured {
        checked.push(Series2D::line(
            c.label.clone(),
            c.points.iter().map(|&(x, y, _)| (x, y)).collect(),
        ));
        let values = c.points.iter().map(|&(_, _, v)| (v, 0.0));
        validate(
            path,
            &[Series2D::line(
                format!("{} ({})", c.label, scale.desc),
                values.chain([(scale.lo, scale.hi)]).collect(),
            )],
        )?;
    }
    let bounds = validate(path, &checked)?;
    let (x_range, y_range) = if equal_scale {
        let (w, h) = plotting_area_px(path, title)?;
        equal_scale_ranges(bounds, w, h)
    } else {
        (padded(bounds.0, bounds.1), padded(bounds.2, bounds.3))
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, CANVAS_PX).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err(path))?;
        let mut chart = chart_builder(&root, title)
            .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
            .map_err(plot_err(path))?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .label_style(("sans-serif", LABEL_FONT_PX))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(plot_err(path))?;

        let mut palette = PALETTE.iter().cycle();
        for s in series {
            let (r, g, b) = s
                .style
                .rgb
                .unwrap_or_else(|| *palette.next().unwrap_or(&PALETTE[0]));
            let color = RGBColor(r, g, b);
            let line_style = color.stroke_width(SERIES_STROKE_PX);
            let pts = s.points.iter().copied();
            let legend = move |(x, y): (i32, i32)| {
                Rectangle::new([(x, y - 4), (x + 18, y + 4)], color.filled())
            };
            match s.style.kind {
                LineKind::Line => chart
                    .draw_series(LineSeries::new(pts, line_style))
                    .map_err(plot_err(path))?
                    .label(s.label.as_str())
                    .legend(legend),
                LineKind::Markers => chart
                    .draw_series(pts.map(|p| Circle::new(p, MARKER_RADIUS_PX, color.filled())))
                    .map_err(plot_err(path))?
                    .label(s.label.as_str())
                    .legend(legend),
                LineKind::LineMarkers => {
                    chart
                        .draw_series(
                            s.points
                                .iter()
                                .map(|&p| Circle::new(p, MARKER_RADIUS_PX, color.filled())),
                        )
                        .map_err(plot_err(path))?;
                    chart
                        .draw_series(LineSeries::new(pts, line_style))
                        .map_err(plot_err(path))?
                        .label(s.label.as_str())
                        .legend(legend)
                }
            };
        }
        if let Some((c, scale)) = coloured {
            for w in c.points.windows(2) {
                let (r, g, b) = scale.rgb(0.5 * (w[0].2 + w[1].2));
                let style = RGBColor(r, g, b).stroke_width(COLOURED_STROKE_PX);
                chart
                    .draw_series(LineSeries::new([(w[0].0, w[0].1), (w[1].0, w[1].1)], style))
                    .map_err(plot_err(path))?;
            }
            // the scale as legend swatches: value at each
            for k in 0..SCALE_SWATCHES {
                let value =
                    scale.lo + (scale.hi - scale.lo) * k as f64 / (SCALE_SWATCHES - 1) as f64;
                let (r, g, b) = scale.rgb(value);
                let color = RGBColor(r, g, b);
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                    .map_err(plot_err(path))?
                    .label(format!("{}: {} {value:.3}", c.label, scale.desc))
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - 4), (x + 18, y + 4)], color.filled())
                    });
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", LABEL_FONT_PX))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err(path))?;
        root.present().map_err(plot_err(path))?;
    }
    Ok(svg)
}

/// Renders, then writes the file (errors name `path`).
fn render_to_file(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series2D],
    coloured: Option<(&ColouredPath, &ColourScale)>,
    equal_scale: bool,
) -> Result<(), ReportError> {
    let svg = render(path, title, x_desc, y_desc, series, coloured, equal_scale)?;
    std::fs::write(path, svg).map_err(|source| ReportError::Io {
        path: PathBuf::from(path),
        source,
    })
}

/// Top view (x_m, y_m) of ego trajectories, e.g. every variant's estimate and
/// the truth (`Series2D::truth`), with equal metres per pixel on both axes.
///
/// # Errors
///
/// [`ReportError`] for no series, an empty or non-finite series, or a failed write.
pub fn plot_trajectories_xy(
    path: &Path,
    title: &str,
    series: &[Series2D],
) -> Result<(), ReportError> {
    render_to_file(path, title, "x [m]", "y [m]", series, None, true)
}

/// Top view of object tracks: truth tracks drawn black unless they carry a
/// colour, estimated tracks in palette colours; equal axis scale.
///
/// # Errors
///
/// [`ReportError`] for no series, an empty or non-finite series, or a failed write.
pub fn plot_object_tracks(
    path: &Path,
    title: &str,
    truth: &[Series2D],
    est: &[Series2D],
) -> Result<(), ReportError> {
    let all: Vec<Series2D> = truth
        .iter()
        .map(|s| {
            let mut s = s.clone();
            s.style.rgb.get_or_insert(TRUTH_RGB);
            s
        })
        .chain(est.iter().cloned())
        .collect();
    render_to_file(path, title, "x [m]", "y [m]", &all, None, true)
}

/// Speed over time: points are (t_s, speed_mps).
///
/// # Errors
///
/// [`ReportError`] for no series, an empty or non-finite series, or a failed write.
pub fn plot_speed(path: &Path, title: &str, series: &[Series2D]) -> Result<(), ReportError> {
    render_to_file(path, title, "t [s]", "speed [m/s]", series, None, false)
}

/// An error over time: points are (t_s, error) with `y_desc` naming the error
/// and its unit, e.g. "translation error \[m\]".
///
/// # Errors
///
/// [`ReportError`] for no series, an empty or non-finite series, or a failed write.
pub fn plot_error_over_time(
    path: &Path,
    title: &str,
    y_desc: &str,
    series: &[Series2D],
) -> Result<(), ReportError> {
    render_to_file(path, title, "t [s]", y_desc, series, None, false)
}

/// Top view of a path coloured by its value per point (`scale` maps values
/// to colours; the legend shows the scale), over `background` series (e.g.
/// the truth in black); equal axis scale.
///
/// # Errors
///
/// [`ReportError`] for an empty or non-finite path or series, or a failed write.
pub fn plot_coloured_path(
    path: &Path,
    title: &str,
    background: &[Series2D],
    coloured: &ColouredPath,
    scale: &ColourScale,
) -> Result<(), ReportError> {
    render_to_file(
        path,
        title,
        "x [m]",
        "y [m]",
        background,
        Some((coloured, scale)),
        true,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_scale_ranges_have_equal_metres_per_pixel() {
        let ((x0, x1), (y0, y1)) = equal_scale_ranges((0.0, 100.0, -5.0, 5.0), 800, 400);
        let mx = (x1 - x0) / 800.0;
        let my = (y1 - y0) / 400.0;
        assert!((mx - my).abs() < 1e-12, "{mx} vs {my}");
        // Data still inside, and the wider axis keeps its 5 % padding.
        assert!(x0 <= 0.0 && x1 >= 100.0 && y0 <= -5.0 && y1 >= 5.0);
        assert!((x1 - x0 - 110.0).abs() < 1e-9);
    }

    #[test]
    fn constant_series_gets_a_nonzero_range() {
        let (lo, hi) = padded(3.0, 3.0);
        assert!(lo < 3.0 && hi > 3.0);
    }

    #[test]
    fn validation_names_series_and_index() {
        let p = Path::new("out/x.svg");
        let s = [Series2D::line("a", vec![(0.0, 0.0), (1.0, f64::INFINITY)])];
        match validate(p, &s) {
            Err(ReportError::NonFinite { label, index, .. }) => {
                assert_eq!((label.as_str(), index), ("a", 1));
            }
            other => panic!("expected NonFinite, got {other:?}"),
        }
        let e = validate(p, &[Series2D::line("b", vec![])]).unwrap_err();
        assert!(matches!(e, ReportError::EmptySeries { .. }));
        assert!(e.to_string().contains("out/x.svg"), "{e}");
        let huge = [Series2D::line("h", vec![(-f64::MAX, 0.0), (f64::MAX, 0.0)])];
        assert!(matches!(validate(p, &huge), Err(ReportError::Plot { .. })));
    }

    #[test]
    fn colour_scale_runs_dark_to_bright_and_clamps() {
        let scale = ColourScale {
            lo: 0.0,
            hi: 0.2,
            desc: "e [m]".into(),
        };
        assert_eq!(scale.rgb(0.0), RAMP[0]);
        assert_eq!(scale.rgb(0.2), RAMP[4]);
        assert_eq!(scale.rgb(0.1), RAMP[2]);
        assert_eq!(scale.rgb(-1.0), RAMP[0]);
        assert_eq!(scale.rgb(9.0), RAMP[4]);
        // halfway between two ramp colours
        let (r, g, b) = scale.rgb(0.025);
        assert_eq!((r, g, b), (64, 42, 112));
        let flat = ColourScale { hi: 0.0, ..scale };
        assert_eq!(flat.rgb(5.0), RAMP[0]);
    }

    #[test]
    fn a_coloured_path_is_drawn_segment_by_segment_with_its_scale() {
        let p = Path::new("out/c.svg");
        let path = ColouredPath {
            label: "lio".into(),
            points: vec![(0.0, 0.0, 0.0), (1.0, 0.0, 0.1), (2.0, 0.0, 0.2)],
        };
        let scale = ColourScale {
            lo: 0.0,
            hi: 0.2,
            desc: "e [m]".into(),
        };
        let truth = [Series2D::truth("truth", vec![(0.0, 0.0), (2.0, 0.0)])];
        let svg = render(p, "t", "x", "y", &truth, Some((&path, &scale)), true).unwrap();
        // two coloured segments, in the colours of their mean values
        for value in [0.05, 0.15] {
            let (r, g, b) = scale.rgb(value);
            let stroke = format!("#{r:02X}{g:02X}{b:02X}");
            assert!(svg.contains(&stroke), "no segment in {stroke}");
        }
        assert!(svg.contains("lio: e [m] 0.200"), "scale legend");
        let bad = ColouredPath {
            points: vec![(0.0, 0.0, f64::NAN)],
            ..path
        };
        let e = render(p, "t", "x", "y", &truth, Some((&bad, &scale)), true).unwrap_err();
        assert!(matches!(e, ReportError::NonFinite { .. }), "{e}");
    }
}
