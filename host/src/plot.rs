//! Small SVG line charts (plotters' SVG backend: no fonts, no external resources), for the
//! thesis figures `cta` redraws (Figures 14-24, 40, 57).

use plotters::coord::combinators::BindKeyPoints;
use plotters::prelude::*;
use std::path::Path;

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points (x, y); non-finite or non-positive-on-log points are dropped.
    pub points: Vec<(f64, f64)>,
    /// Draw dashed (e.g. a noise floor or an uncertainty).
    pub dashed: bool,
}

impl Series {
    /// A solid curve.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            label: label.into(),
            points,
            dashed: false,
        }
    }
    /// A dashed curve.
    pub fn dashed(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            label: label.into(),
            points,
            dashed: true,
        }
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

/// The corner for the legend: the one whose quarter-ish box holds the fewest data points
/// (sampled along the lines), upper right first on a tie.
fn legend_corner(p: &Panel, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> SeriesLabelPosition {
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
    let mut pts = Vec::new();
    for s in &p.series {
        let q: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|q| q.0.is_finite() && q.1.is_finite())
            .filter(|q| (!p.log_x || q.0 > 0.0) && (!p.log_y || q.1 > 0.0))
            .map(|q| (norm(q.0, x0, x1, p.log_x), norm(q.1, y0, y1, p.log_y)))
            .collect();
        for w in q.windows(2) {
            for k in 0..8 {
                let f = k as f64 / 8.0;
                pts.push((
                    w[0].0 + f * (w[1].0 - w[0].0),
                    w[0].1 + f * (w[1].1 - w[0].1),
                ));
            }
        }
        pts.extend(q.last().copied());
    }
    let (bw, bh) = (0.45, 0.45);
    let corners = [
        (
            SeriesLabelPosition::UpperRight,
            1.0 - bw,
            1.0,
            1.0 - bh,
            1.0,
        ),
        (SeriesLabelPosition::UpperLeft, 0.0, bw, 1.0 - bh, 1.0),
        (SeriesLabelPosition::LowerRight, 1.0 - bw, 1.0, 0.0, bh),
        (SeriesLabelPosition::LowerLeft, 0.0, bw, 0.0, bh),
    ];
    let mut best = (usize::MAX, SeriesLabelPosition::UpperRight);
    for (pos, xa, xb, ya, yb) in corners {
        let n = pts
            .iter()
            .filter(|(x, y)| *x >= xa && *x <= xb && *y >= ya && *y <= yb)
            .count();
        if n < best.0 {
            best = (n, pos);
        }
    }
    best.1
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

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let keep = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
    };
    let xs = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().filter(|q| keep(q.0, q.1)).map(|q| q.0));
    let ys = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().filter(|q| keep(q.0, q.1)).map(|q| q.1));
    let (x0, x1) = range(xs, p.log_x);
    let (y0, y1) = range(ys, p.log_y);
    let legend_at = legend_corner(p, (x0, x1), (y0, y1));
    let mut b = ChartBuilder::on(area);
    b.caption(&p.title, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(60);
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
                    c.draw_series(DashedLineSeries::new(pts, 6, 4, style))
                        .map_err(e)?
                        .label(s.label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col));
                } else {
                    c.draw_series(LineSeries::new(pts, style))
                        .map_err(e)?
                        .label(s.label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], col));
                }
            }
            c.configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .position(legend_at)
                .draw()
                .map_err(e)?;
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
    Ok(())
}

/// Tick positions on a log axis: 1, 2, 5 per decade (1 per decade over wide ranges).
fn log_keys(lo: f64, hi: f64) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let mult: &[f64] = if b - a > 4 { &[1.0] } else { &[1.0, 2.0, 5.0] };
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
pub fn render_svg(title: &str, panels: &[Panel], cols: usize) -> Result<String, String> {
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let (w, h) = (520 * cols as u32, 380 * rows as u32 + 40);
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 20))
            .map_err(|e| e.to_string())?;
        let areas = root.split_evenly((rows, cols));
        for (a, p) in areas.iter().zip(panels) {
            draw_panel(a, p)?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(buf)
}

/// Render panels to an SVG file.
pub fn write_svg(path: &Path, title: &str, panels: &[Panel], cols: usize) -> anyhow::Result<()> {
    refuse_to_replace_non_svg(path)?;
    let svg = render_svg(title, panels, cols)
        .map_err(|e| anyhow::anyhow!("{}: plotting failed: {e}", path.display()))?;
    std::fs::write(path, svg).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(())
}

/// A plot may replace an earlier plot, never another kind of file (`--plot data.csv` by
/// mistake would otherwise destroy the measurements).
pub fn refuse_to_replace_non_svg(path: &Path) -> anyhow::Result<()> {
    use std::io::Read;
    if !path.exists() {
        return Ok(());
    }
    if path.is_dir() {
        anyhow::bail!(
            "{}: is a folder; give a file name for the plot",
            path.display()
        );
    }
    let mut head = [0u8; 256];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let text = String::from_utf8_lossy(&head[..n]);
    let t = text.trim_start();
    if !(t.starts_with("<svg") || (t.starts_with("<?xml") && text.contains("<svg"))) {
        anyhow::bail!(
            "{}: exists and is not an SVG plot: not replacing it (choose another name, or remove the file)",
            path.display()
        );
    }
    Ok(())
}
