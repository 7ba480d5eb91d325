//! Small SVG line charts (plotters' SVG backend: no fonts, no external resources), for the
//! thesis figures `cta` redraws (Figures 14-24, 40, 57).

use plotters::coord::combinators::BindKeyPoints;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};

use crate::data::OutputError;

/// Why a plot or report was not written, or may not be.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The path is a folder.
    #[error("{}: is a folder; give a file name for the output", .path.display())]
    IsFolder {
        /// The path.
        path: PathBuf,
    },
    /// An existing file that cannot be read, so it is not known to be `cta`'s.
    #[error(
        "{}: exists and cannot be read ({error}), so it is not known to be an earlier cta \
         output: not replacing it (choose another name, or remove the file)",
        .path.display()
    )]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why it cannot be read.
        error: std::io::Error,
    },
    /// An existing file `cta` did not write.
    #[error(
        "{}: exists and is not a plot or report cta wrote: not replacing it (choose another \
         name, or remove the file)",
        .path.display()
    )]
    NotOurs {
        /// The file.
        path: PathBuf,
    },
    /// A plot named other than `.svg`.
    #[error("{}: plots are SVG files: give a name ending in .svg", .path.display())]
    NotSvg {
        /// The path.
        path: PathBuf,
    },
    /// The chart could not be drawn.
    #[error("{}: plotting failed: {error}", .path.display())]
    Render {
        /// The plot's path.
        path: PathBuf,
        /// What plotters said.
        error: RenderError,
    },
    /// The file could not be written.
    #[error(transparent)]
    Write(#[from] OutputError),
}

/// A chart plotters could not draw (its message).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RenderError(pub String);

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points (x, y); non-finite or non-positive-on-log points are dropped.
    pub points: Vec<(f64, f64)>,
    /// Draw dashed (e.g. a noise floor or an uncertainty).
    pub dashed: bool,
    /// Mark each point (a solid series of at most [`MARKERS_UP_TO`] points is marked anyway,
    /// so that a few points joined by straight lines do not read as a measured curve).
    pub markers: bool,
    /// Error bars: for each point (same order), the half-length in y; empty for none. A
    /// non-finite or non-positive entry draws no bar.
    pub y_err: Vec<f64>,
    /// The panel's (linear) y axis starts at 0 (or below, for negative data), so that the
    /// series is read against its size, not against its own spread: a noise level whose
    /// points scatter by their sampling error would otherwise fill the panel and look like
    /// structure.
    pub y_from_zero: bool,
}

/// A solid series with at most this many points is drawn with markers.
pub const MARKERS_UP_TO: usize = 15;

impl Series {
    /// A solid curve.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            label: label.into(),
            points,
            dashed: false,
            markers: false,
            y_err: Vec::new(),
            y_from_zero: false,
        }
    }
    /// A dashed curve.
    pub fn dashed(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            label: label.into(),
            points,
            dashed: true,
            markers: false,
            y_err: Vec::new(),
            y_from_zero: false,
        }
    }
    /// Mark each point.
    pub fn with_markers(mut self) -> Self {
        self.markers = true;
        self
    }
    /// Start the panel's y axis at 0 (see [`Series::y_from_zero`]; ignored on a log axis).
    pub fn from_zero(mut self) -> Self {
        self.y_from_zero = true;
        self
    }
    /// Draw error bars: `y +/- err[i]` at point `i`.
    pub fn with_error_bars(mut self, err: Vec<f64>) -> Self {
        self.y_err = err;
        self
    }
    /// Whether the points are marked (asked for, or a solid series of few points).
    fn marked(&self) -> bool {
        self.markers || (!self.dashed && self.points.len() <= MARKERS_UP_TO)
    }
    /// The error bars that are drawn: (x, y low, y, y high).
    fn bars(&self) -> impl Iterator<Item = (f64, f64, f64, f64)> + '_ {
        self.points
            .iter()
            .zip(&self.y_err)
            .filter(|(_, e)| e.is_finite() && **e > 0.0)
            .map(|(&(x, y), &e)| (x, y - e, y, y + e))
    }
}

/// One panel of a figure.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Panel title.
    pub title: String,
    /// X axis label.
    pub x_desc: String,
    /// Y axis label.
    pub y_desc: String,
    /// Logarithmic x.
    pub log_x: bool,
    /// Logarithmic y.
    pub log_y: bool,
    /// Curves.
    pub series: Vec<Series>,
}

/// Where the legend goes: a corner of the plot where its box covers no data (the first of
/// upper right, upper left, lower right, lower left), or, when every corner holds data,
/// below the plot.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LegendAt {
    Inside(Corner),
    Below,
}

/// A corner of the plot.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Corner {
    UpperRight,
    UpperLeft,
    LowerRight,
    LowerLeft,
}

/// Whether the segment `a`-`b` (normalised plot coordinates) meets the box
/// `[x0, x1] x [y0, y1]` (Liang-Barsky clipping).
fn segment_meets_box(a: (f64, f64), b: (f64, f64), (x0, x1, y0, y1): (f64, f64, f64, f64)) -> bool {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    t0 <= t1
}

/// The legend's place, for a legend box of `(bw, bh)` as fractions of the plot (its lines,
/// markers and error bars are the data it must not cover).
fn legend_place(
    p: &Panel,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    (bw, bh): (f64, f64),
) -> LegendAt {
    let norm = |v: f64, lo: f64, hi: f64, log: bool| {
        let (v, lo, hi) = if log {
            (v.ln(), lo.ln(), hi.ln())
        } else {
            (v, lo, hi)
        };
        if hi > lo {
            (v - lo) / (hi - lo)
        } else {
            0.5
        }
    };
    let keep = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
    };
    let to = |x: f64, y: f64| (norm(x, x0, x1, p.log_x), norm(y, y0, y1, p.log_y));
    // Segments: the lines, a short cross at each point (its marker), the error bars.
    let mut segs: Vec<((f64, f64), (f64, f64))> = Vec::new();
    for s in &p.series {
        let q: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|q| keep(q.0, q.1))
            .map(|q| to(q.0, q.1))
            .collect();
        segs.extend(q.windows(2).map(|w| (w[0], w[1])));
        let r = 0.015;
        for &(x, y) in &q {
            segs.push(((x - r, y), (x + r, y)));
            segs.push(((x, y - r), (x, y + r)));
        }
        for (x, lo, _, hi) in s.bars() {
            let lo = if p.log_y && lo <= 0.0 { y0 } else { lo };
            if keep(x, lo) && keep(x, hi) {
                segs.push((to(x, lo), to(x, hi)));
            }
        }
    }
    let corners = [
        (Corner::UpperRight, 1.0 - bw, 1.0, 1.0 - bh, 1.0),
        (Corner::UpperLeft, 0.0, bw, 1.0 - bh, 1.0),
        (Corner::LowerRight, 1.0 - bw, 1.0, 0.0, bh),
        (Corner::LowerLeft, 0.0, bw, 0.0, bh),
    ];
    for (pos, xa, xb, ya, yb) in corners {
        if bw < 1.0
            && bh < 1.0
            && !segs
                .iter()
                .any(|&(a, b)| segment_meets_box(a, b, (xa, xb, ya, yb)))
        {
            return LegendAt::Inside(pos);
        }
    }
    LegendAt::Below
}

/// The series that have a legend entry.
fn labelled(p: &Panel) -> impl Iterator<Item = (usize, &Series)> {
    p.series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.is_empty())
}

/// Legend font.
const LEGEND_FONT: (&str, u32) = ("sans-serif", 12);
/// Room for the sample line and marker before each legend label, pixels.
const LEGEND_KEY: i32 = 26;
/// Padding inside the legend box, pixels.
const LEGEND_PAD: i32 = 6;
/// Height of one legend row, pixels.
const LEGEND_ROW: i32 = 16;
/// Gap between the plot's edge and a legend inside it, pixels.
const LEGEND_GAP: i32 = 5;

/// Width of the widest legend label, pixels (plotters' estimate: the SVG has no fonts).
fn label_width(p: &Panel) -> i32 {
    let font = LEGEND_FONT.into_font();
    labelled(p)
        .map(|(_, s)| font.box_size(&s.label).map(|b| b.0 as i32).unwrap_or(200))
        .max()
        .unwrap_or(0)
}

/// The legend's size in pixels with its entries in `cols` columns.
fn legend_size(p: &Panel, cols: usize) -> (i32, i32) {
    let n = labelled(p).count();
    let rows = n.div_ceil(cols.max(1)) as i32;
    (
        cols as i32 * (label_width(p) + LEGEND_KEY) + 2 * LEGEND_PAD,
        rows * LEGEND_ROW + 2 * LEGEND_PAD,
    )
}

/// Draw the legend with its top left corner at `at` (pixels of `area`), entries in `cols`
/// columns, framed (inside the plot) or not (below it).
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
    at: (i32, i32),
    cols: usize,
    framed: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let cols = cols.max(1);
    let (w, h) = legend_size(p, cols);
    if framed {
        let corners = [at, (at.0 + w, at.1 + h)];
        area.draw(&Rectangle::new(corners, WHITE.mix(0.85).filled()))?;
        area.draw(&Rectangle::new(corners, BLACK))?;
    }
    let col_w = label_width(p) + LEGEND_KEY;
    for (j, (k, s)) in labelled(p).enumerate() {
        let col = COLORS[k % COLORS.len()];
        let x = at.0 + LEGEND_PAD + (j % cols) as i32 * col_w;
        let y = at.1 + LEGEND_PAD + (j / cols) as i32 * LEGEND_ROW + LEGEND_ROW / 2;
        let style = ShapeStyle {
            color: col.to_rgba(),
            filled: false,
            stroke_width: 2,
        };
        if s.dashed {
            area.draw(&PathElement::new(vec![(x, y), (x + 7, y)], style))?;
            area.draw(&PathElement::new(vec![(x + 11, y), (x + 18, y)], style))?;
        } else {
            area.draw(&PathElement::new(vec![(x, y), (x + 18, y)], style))?;
        }
        if s.marked() {
            area.draw(&Circle::new((x + 9, y), 3, col.filled()))?;
        }
        let font = LEGEND_FONT
            .into_font()
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        area.draw(&Text::new(s.label.clone(), (x + LEGEND_KEY - 4, y), font))?;
    }
    Ok(())
}

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn range(vals: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals {
        if v.is_finite() && (!log || v > 0.0) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return if log { (0.1, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.2, hi * 1.2)
    } else if hi == lo {
        (lo - 1.0, hi + 1.0)
    } else {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

/// The y range of a panel: its points and error bars, padded (see [`range`]); from 0 when a
/// series asks for it ([`Series::y_from_zero`]) and the axis is linear.
fn y_range(p: &Panel) -> (f64, f64) {
    let keep = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
    };
    // The y range holds the error bars too.
    let ys: Vec<f64> = p
        .series
        .iter()
        .flat_map(|s| {
            s.points
                .iter()
                .filter(|q| keep(q.0, q.1))
                .map(|q| q.1)
                .chain(s.bars().flat_map(|(_, lo, _, hi)| [lo, hi]))
        })
        .collect();
    if p.log_y || !p.series.iter().any(|s| s.y_from_zero) {
        return range(ys.into_iter(), p.log_y);
    }
    // 0 is one of the values; with no negative data the axis starts exactly there (no padding
    // below it), and the top is padded as usual.
    let nonneg = ys.iter().all(|v| !v.is_finite() || *v >= 0.0);
    let (lo, hi) = range(ys.into_iter().chain([0.0]), false);
    (if nonneg { 0.0 } else { lo }, hi)
}

/// Margin around a panel, pixels.
const MARGIN: i32 = 12;
/// Room for the x tick labels and description, pixels.
const X_LABEL_AREA: i32 = 36;
/// Room for the y tick labels and description, pixels.
const Y_LABEL_AREA: i32 = 60;
/// Panel caption font.
const CAPTION_FONT: (&str, u32) = ("sans-serif", 16);

/// The size in pixels of the plot inside a panel of `(w, h)` pixels (laid out once on a
/// scratch canvas: the caption's height is plotters' own).
fn plot_size(title: &str, (w, h): (u32, u32)) -> (i32, i32) {
    let mut scratch = String::new();
    let root = SVGBackend::with_string(&mut scratch, (w.max(1), h.max(1))).into_drawing_area();
    let mut b = ChartBuilder::on(&root);
    b.caption(title, CAPTION_FONT)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    let size = match b.build_cartesian_2d(0.0..1.0, 0.0..1.0) {
        Ok(c) => {
            let (pw, ph) = c.plotting_area().dim_in_pixel();
            (pw as i32, ph as i32)
        }
        Err(_) => (w as i32, h as i32),
    };
    size
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
) -> Result<(), RenderError>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| RenderError(e.to_string());
    let keep = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
    };
    let xs = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().filter(|q| keep(q.0, q.1)).map(|q| q.0));
    let (x0, x1) = range(xs, p.log_x);
    let (y0, y1) = y_range(p);
    // The legend: in a corner of the plot where it covers no data, else below the plot.
    let (aw, ah) = area.dim_in_pixel();
    let (pw, ph) = plot_size(&p.title, (aw, ah));
    let (lw, lh) = legend_size(p, 1);
    let place = if labelled(p).next().is_none() {
        None
    } else {
        let frac = |l: i32, full: i32| f64::from(l + LEGEND_GAP) / f64::from(full.max(1));
        Some(legend_place(
            p,
            (x0, x1),
            (y0, y1),
            (frac(lw, pw), frac(lh, ph)),
        ))
    };
    let (chart_area, below) = if place == Some(LegendAt::Below) {
        let n = labelled(p).count();
        let col_w = label_width(p) + LEGEND_KEY;
        let cols = ((aw as i32 - 2 * MARGIN - Y_LABEL_AREA) / col_w.max(1)).clamp(1, n as i32);
        let (_, h) = legend_size(p, cols as usize);
        let (top, bottom) = area.split_vertically(ah as i32 - h);
        (top, Some((bottom, cols as usize)))
    } else {
        (area.clone(), None)
    };
    let mut b = ChartBuilder::on(&chart_area);
    b.caption(&p.title, CAPTION_FONT)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    macro_rules! body {
        ($chart:expr) => {{
            let mut c = $chart;
            c.configure_mesh()
                .x_desc(p.x_desc.as_str())
                .y_desc(p.y_desc.as_str())
                .x_label_formatter(&|v: &f64| tick(*v))
                .y_label_formatter(&|v: &f64| tick(*v))
                .draw()
                .map_err(e)?;
            for (k, s) in p.series.iter().enumerate() {
                let col = COLORS[k % COLORS.len()];
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|q| keep(q.0, q.1))
                    .collect();
                let style = ShapeStyle {
                    color: col.to_rgba(),
                    filled: false,
                    stroke_width: 2,
                };
                if s.dashed {
                    c.draw_series(DashedLineSeries::new(pts.clone(), 6, 4, style))
                        .map_err(e)?;
                } else {
                    c.draw_series(LineSeries::new(pts.clone(), style))
                        .map_err(e)?;
                }
                if s.marked() {
                    c.draw_series(pts.iter().map(|&q| Circle::new(q, 3, col.filled())))
                        .map_err(e)?;
                }
                let bar = ShapeStyle {
                    color: col.to_rgba(),
                    filled: false,
                    stroke_width: 1,
                };
                let bars: Vec<_> = s
                    .bars()
                    .map(|(x, lo, y, hi)| (x, if p.log_y && lo <= 0.0 { y0 } else { lo }, y, hi))
                    .filter(|&(x, lo, y, hi)| keep(x, lo) && keep(x, y) && keep(x, hi))
                    .collect();
                for (x, lo, _, hi) in bars {
                    c.draw_series([PathElement::new(vec![(x, lo), (x, hi)], bar)])
                        .map_err(e)?;
                    for end in [lo, hi] {
                        c.draw_series([EmptyElement::at((x, end))
                            + PathElement::new(vec![(-4, 0), (4, 0)], bar)])
                            .map_err(e)?;
                    }
                }
            }
            if let Some(LegendAt::Inside(pos)) = place {
                let plot = c.plotting_area().strip_coord_spec();
                let (w, h) = plot.dim_in_pixel();
                let (w, h) = (w as i32, h as i32);
                let at = match pos {
                    Corner::UpperRight => (w - lw - LEGEND_GAP, LEGEND_GAP),
                    Corner::UpperLeft => (LEGEND_GAP, LEGEND_GAP),
                    Corner::LowerRight => (w - lw - LEGEND_GAP, h - lh - LEGEND_GAP),
                    Corner::LowerLeft => (LEGEND_GAP, h - lh - LEGEND_GAP),
                };
                draw_legend(&plot, p, at, 1, true).map_err(e)?;
            }
        }};
    }
    match (p.log_x, p.log_y) {
        (false, false) => body!(b.build_cartesian_2d(x0..x1, y0..y1).map_err(e)?),
        (true, false) => body!(b
            .build_cartesian_2d(
                (x0..x1).log_scale().with_key_points(log_keys(x0, x1)),
                y0..y1
            )
            .map_err(e)?),
        (false, true) => body!(b
            .build_cartesian_2d(
                x0..x1,
                (y0..y1).log_scale().with_key_points(log_keys(y0, y1))
            )
            .map_err(e)?),
        (true, true) => body!(b
            .build_cartesian_2d(
                (x0..x1).log_scale().with_key_points(log_keys(x0, x1)),
                (y0..y1).log_scale().with_key_points(log_keys(y0, y1))
            )
            .map_err(e)?),
    }
    if let Some((bottom, cols)) = below {
        draw_legend(&bottom, p, (MARGIN + Y_LABEL_AREA, 0), cols, false).map_err(e)?;
    }
    Ok(())
}

/// The fewest labelled ticks a log axis gets.
const MIN_LOG_TICKS: usize = 3;

/// Tick positions on a log axis: 1, 2, 5 per decade (1 per decade over wide ranges); 1 to 9
/// per decade when that gives fewer than [`MIN_LOG_TICKS`], and evenly spaced round values
/// (a step of 1, 2 or 5 times a power of 10) when even that does (a range well under a
/// decade, e.g. 28 to 34).
fn log_keys(lo: f64, hi: f64) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let keys = |mult: &[f64]| {
        let mut v = Vec::new();
        for k in a..=b {
            for m in mult {
                let x: f64 = format!("{m}e{k}").parse().unwrap_or(f64::NAN);
                if x >= lo && x <= hi {
                    v.push(x);
                }
            }
        }
        v
    };
    let v = keys(if b - a > 4 { &[1.0] } else { &[1.0, 2.0, 5.0] });
    if v.len() >= MIN_LOG_TICKS || !(lo > 0.0 && hi > lo) {
        return v;
    }
    let v = keys(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if v.len() >= MIN_LOG_TICKS {
        return v;
    }
    let raw = (hi - lo) / 5.0;
    let p10 = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p10)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p10);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last)
        .map(|k| format!("{:e}", k as f64 * step).parse().unwrap_or(f64::NAN))
        .filter(|x: &f64| *x > 0.0)
        .collect()
}

/// A tick label with at most 3 significant digits and no float noise.
pub fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-3..5).contains(&mag) {
        return format!("{v:.1e}");
    }
    let decimals = (2 - mag).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Render panels on a grid (`cols` wide) to an SVG string.
pub fn render_svg(title: &str, panels: &[Panel], cols: usize) -> Result<String, RenderError> {
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let (w, h) = (520 * cols as u32, 380 * rows as u32 + 40);
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<_>| RenderError(e.to_string());
        root.fill(&WHITE).map_err(e)?;
        let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
        let areas = root.split_evenly((rows, cols));
        for (a, p) in areas.iter().zip(panels) {
            draw_panel(a, p)?;
        }
        root.present().map_err(e)?;
    }
    Ok(buf)
}

/// The comment every file `cta` writes for people to look at (plots, HTML reports) carries
/// near its start: such a file, and only such a file, a later `cta` output may replace
/// ([`refuse_to_replace`]).
pub const MARK: &str = "<!-- written by cta; a later cta output may replace this file -->";

/// Files written before [`MARK`] existed, recognised by their first bytes: plotters' SVG
/// header as `cta` wrote it, and the two HTML reports.
const LEGACY_HEADS: [&str; 3] = [
    "<svg width=\"",
    "<!doctype html><html><head><meta charset=utf-8><title>cta analyze: ",
    "<!doctype html><meta charset=utf-8><title>cta noise</title>",
];

/// The first 512 bytes of the file at `path`, as text.
fn read_head(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut head = Vec::new();
    std::fs::File::open(path)?
        .take(512)
        .read_to_end(&mut head)?;
    Ok(String::from_utf8_lossy(&head).into_owned())
}

/// Whether the file at `path` is one `cta` wrote ([`written_by_cta`]); false when it cannot be
/// read.
pub fn is_cta_output(path: &Path) -> bool {
    read_head(path).is_ok_and(|h| written_by_cta(&h))
}

/// Whether the first bytes of a file show that `cta` wrote it ([`MARK`], or an older plot or
/// report's exact header).
fn written_by_cta(head: &str) -> bool {
    head.contains(MARK)
        || head.starts_with(LEGACY_HEADS[0])
            && head.lines().next().is_some_and(|l| {
                l.ends_with(" xmlns=\"http://www.w3.org/2000/svg\">")
                    && l.contains(" viewBox=\"0 0 ")
                    && l.matches('=').count() == 4
            })
        || LEGACY_HEADS[1..].iter().any(|h| head.starts_with(h))
}

/// Render panels to an SVG file, written as every `cta` output is
/// ([`crate::data::write_output`]) and marked as `cta`'s ([`MARK`]); refused when `path`
/// holds a file `cta` did not write. The caller announces it (`plot: PATH`).
pub fn write_svg(path: &Path, title: &str, panels: &[Panel], cols: usize) -> Result<(), PlotError> {
    check_plot_path(path)?;
    let svg = render_svg(title, panels, cols).map_err(|error| PlotError::Render {
        path: path.to_path_buf(),
        error,
    })?;
    write_marked(path, &svg)?;
    Ok(())
}

/// Whether `--plot PATH` may be written: a name ending in `.svg` (plots are SVG: an SVG in
/// `out.png` opens nowhere) that is new or an earlier `cta` output ([`refuse_to_replace`]).
/// Checked before the work, so a bad name costs nothing.
pub fn check_plot_path(path: &Path) -> Result<(), PlotError> {
    refuse_to_replace(path)?;
    let svg = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    if !svg {
        return Err(PlotError::NotSvg {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

/// Write `text` (SVG or HTML) to `path` with [`MARK`] near its start: after an HTML doctype
/// (a comment before it would put browsers in quirks mode), inside an SVG's root element
/// after its opening tag (a comment before the root makes content sniffers take the file for
/// SGML, not `image/svg+xml`), else first.
pub fn write_marked(path: &Path, text: &str) -> Result<(), OutputError> {
    let marked = if let Some(rest) = text.strip_prefix("<!doctype html>") {
        format!("<!doctype html>{MARK}\n{rest}")
    } else if let (true, Some(end)) = (text.starts_with("<svg"), text.find('>')) {
        format!("{}\n{MARK}{}", &text[..=end], &text[end + 1..])
    } else {
        format!("{MARK}\n{text}")
    };
    crate::data::write_output(path, marked.as_bytes())
}

/// A plot or report may replace an earlier one `cta` wrote, never another file: not
/// `--plot data.csv` by mistake, which would destroy the measurements, nor a lab's own SVG
/// or web page (`--report site/` over `site/index.html`). `cta`'s files carry [`MARK`].
pub fn refuse_to_replace(path: &Path) -> Result<(), PlotError> {
    if !path.exists() {
        return Ok(());
    }
    if path.is_dir() {
        return Err(PlotError::IsFolder {
            path: path.to_path_buf(),
        });
    }
    let head = read_head(path).map_err(|error| PlotError::Unreadable {
        path: path.to_path_buf(),
        error,
    })?;
    if !written_by_cta(&head) {
        return Err(PlotError::NotOurs {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {

    /// Files cta wrote, marked or from before the mark, are recognised; a lab's own SVG,
    /// even one shaped like plotters' header with one more attribute, and web pages are not.
    #[test]
    fn cta_outputs_are_recognised_by_their_first_bytes() {
        let svg = render_svg("t", &[], 1).unwrap();
        let older = svg.clone();
        assert!(written_by_cta(&older), "{older:.200}");
        let d = std::env::temp_dir().join(format!("cta-mark-{}", std::process::id()));
        let f = d.join("p.svg");
        write_marked(&f, &svg).unwrap();
        let marked = std::fs::read_to_string(&f).unwrap();
        assert!(
            marked.starts_with("<svg ") && written_by_cta(&marked),
            "{marked:.200}"
        );
        std::fs::remove_dir_all(&d).unwrap();
        for head in [
            "<!doctype html><html><head><meta charset=utf-8><title>cta analyze: a.csv</title>",
            "<!doctype html><meta charset=utf-8><title>cta noise</title><body>",
        ] {
            assert!(written_by_cta(head), "{head}");
        }
        for foreign in [
            "<svg xmlns=\"http://www.w3.org/2000/svg\"><!-- lab schematic --></svg>",
            "<svg width=\"10\" height=\"10\" viewBox=\"0 0 10 10\" id=\"mine\" xmlns=\"http://www.w3.org/2000/svg\">\n",
            "<?xml version=\"1.0\"?>\n<svg width=\"10\" height=\"10\" viewBox=\"0 0 10 10\" xmlns=\"http://www.w3.org/2000/svg\">",
            "<!doctype html><html><head><title>my wiki</title>",
            "separation_in,x_in",
        ] {
            assert!(!written_by_cta(foreign), "{foreign}");
        }
    }
    use super::*;

    #[test]
    fn a_log_axis_under_a_decade_gets_several_ticks() {
        // 28 to 34 counts padded by 1.2 (the noise plot's zoom): one tick (30) before.
        for (lo, hi) in [
            (28.0 / 1.2, 34.0 * 1.2),
            (0.9, 1.3),
            (150.0, 900.0),
            (3.0, 7.0),
        ] {
            let k = log_keys(lo, hi);
            assert!(k.len() >= MIN_LOG_TICKS, "{lo}..{hi}: {k:?}");
            assert!(k.windows(2).all(|w| w[0] < w[1]), "{k:?}");
            assert!(k.iter().all(|v| *v >= lo && *v <= hi), "{k:?}");
        }
        assert_eq!(
            log_keys(0.9, 110.0),
            vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
        );
    }

    fn panel(series: Vec<Series>) -> Panel {
        Panel {
            title: "t".into(),
            x_desc: "x".into(),
            y_desc: "y".into(),
            log_x: false,
            log_y: false,
            series,
        }
    }

    #[test]
    fn the_legend_covers_no_data() {
        // A diagonal from lower left to upper right: the other two corners are free.
        let diag = panel(vec![Series::new("a", vec![(0.0, 0.0), (1.0, 1.0)])]);
        assert_eq!(
            legend_place(&diag, (0.0, 1.0), (0.0, 1.0), (0.3, 0.2)),
            LegendAt::Inside(Corner::UpperLeft)
        );
        // Curves along the top and the bottom edges: no corner is free, so below the plot.
        let edges = panel(vec![
            Series::new("top", vec![(0.0, 0.95), (1.0, 0.95)]),
            Series::dashed("bottom", vec![(0.0, 0.05), (1.0, 0.05)]),
        ]);
        assert_eq!(
            legend_place(&edges, (0.0, 1.0), (0.0, 1.0), (0.3, 0.2)),
            LegendAt::Below
        );
        // An error bar reaching into a corner occupies it.
        let bar = panel(vec![
            Series::new("a", vec![(0.0, 0.5), (1.0, 0.5)]).with_error_bars(vec![0.0, 0.45])
        ]);
        assert_eq!(
            legend_place(&bar, (0.0, 1.0), (0.0, 1.0), (0.3, 0.3)),
            LegendAt::Inside(Corner::UpperLeft)
        );
    }

    #[test]
    fn a_series_from_zero_puts_zero_on_the_axis() {
        // A noise level of about 33 counts scattering by its +/-0.5 s.e.
        let pts = vec![(2.0, 33.3), (10.0, 34.0), (20.0, 31.2), (30.0, 32.8)];
        let se = vec![0.5; 4];
        let zoomed = panel(vec![
            Series::new("X", pts.clone()).with_error_bars(se.clone())
        ]);
        let (y0, y1) = y_range(&zoomed);
        assert!(y0 > 30.0 && y1 < 35.0, "{y0}..{y1}");
        let anchored = panel(vec![Series::new("X", pts).with_error_bars(se).from_zero()]);
        let (y0, y1) = y_range(&anchored);
        assert_eq!(y0, 0.0);
        assert!(y1 > 34.5 && y1 < 40.0, "{y1}");
        // Negative data keep their room below 0.
        let neg = panel(vec![
            Series::new("d", vec![(0.0, -1.0), (1.0, 3.0)]).from_zero()
        ]);
        assert!(y_range(&neg).0 < -1.0);
        // A log axis ignores it.
        let mut log = anchored.clone();
        log.log_y = true;
        assert!(y_range(&log).0 > 20.0);
    }

    #[test]
    fn few_points_are_marked() {
        let svg = render_svg(
            "",
            &[panel(vec![Series::new(
                "a",
                vec![(1.0, 1.0), (30.0, 2.0), (100.0, 0.5)],
            )])],
            1,
        )
        .unwrap();
        assert_eq!(
            svg.matches("<circle").count(),
            3 + 1,
            "3 points and the legend's key"
        );
    }
}
