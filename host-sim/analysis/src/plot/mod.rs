//! The reports' plots, through `plotters` (SVG into a string, the SVG's own `<text>`, so no
//! font files): one way to draw for the diagnosis, identification and closed-loop reports.
//!
//! A [`Plot`] is a title, axes with units, and layers (lines, points, error bars, dashed
//! levels) on a primary or a secondary y axis. Axes run over whole 1-2-5 steps ([`ticks`]);
//! a line of more than [`LONG`] samples is drawn as its per-pixel-column first/min/max/last
//! ([`envelope::m4`]), a scatter of more than [`LONG`] points as one point per pixel cell, so a
//! 120 000-sample residual shows its spikes and its band instead of a blur. [`interactive`]
//! adds a zoomable view of the long lines to an HTML report, offline.
//!
//! A plot that cannot be drawn (plotters reports an error) becomes an SVG saying so: a report is
//! never lost to one of its pictures.

pub mod envelope;
pub mod interactive;
pub mod ticks;

use std::fmt::Write as _;
use std::ops::Range;

use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, Ranged, ValueFormatter};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

pub use ticks::Axis;

/// Above this many samples a line is drawn as its envelope and a scatter thinned per pixel.
pub const LONG: usize = 2000;

/// The report palette (colour-blind safe, Dark2/Tableau).
pub mod colour {
    pub const GREEN: &str = "#1b9e77";
    pub const ORANGE: &str = "#d95f02";
    pub const PURPLE: &str = "#7570b3";
    pub const BLUE: &str = "#1f77b4";
    pub const RED: &str = "#d62728";
    pub const GREY: &str = "#888888";
    pub const BLACK: &str = "#111111";
    pub const NAVY: &str = "#223366";
    pub const BROWN: &str = "#aa6600";
}

/// How a layer is drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum Mark {
    /// a line through the points in order
    Line { width: u32 },
    /// filled dots
    Points { radius: u32 },
    /// crosses (an outcome that failed)
    Crosses { size: u32 },
    /// vertical bars `y ± half` with caps
    ErrorBars { half: Vec<f64> },
    /// a dashed horizontal level at each `y` (x is ignored)
    Level,
}

/// One layer of a plot.
#[derive(Clone, Debug)]
pub struct Layer {
    /// legend entry; empty: none
    pub name: String,
    pub colour: &'static str,
    pub mark: Mark,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    /// on the secondary (right) y axis
    pub secondary: bool,
    /// hover text per point (an SVG `<title>`), empty for none
    pub tips: Vec<String>,
}

/// A plot: build with [`Plot::new`] and the layer methods, draw with [`Plot::svg`].
#[derive(Clone, Debug)]
pub struct Plot {
    /// the `id` of the `<svg class="plot">` (empty: none)
    pub id: String,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// the secondary axis' label, when a layer uses it
    pub y2_label: String,
    pub size: (u32, u32),
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    pub y2_range: Option<(f64, f64)>,
    /// the y axis always shows zero (residuals, torques from zero)
    pub y_zero: bool,
    /// a categorical y axis: name k sits at y = k + 1 (a ranking, say)
    pub y_names: Vec<String>,
    /// the legend in the upper left corner (for data that rise to the right)
    pub legend_left: bool,
    pub layers: Vec<Layer>,
}

impl Plot {
    pub fn new(id: &str, title: &str, x_label: &str, y_label: &str) -> Plot {
        Plot {
            id: id.into(),
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            y2_label: String::new(),
            size: (640, 360),
            x_range: None,
            y_range: None,
            y2_range: None,
            y_zero: false,
            y_names: Vec::new(),
            legend_left: false,
            layers: Vec::new(),
        }
    }

    pub fn size(mut self, w: u32, h: u32) -> Plot {
        self.size = (w, h);
        self
    }

    fn layer(mut self, name: &str, colour: &'static str, mark: Mark, x: Vec<f64>, y: Vec<f64>) -> Plot {
        self.layers.push(Layer { name: name.into(), colour, mark, x, y, secondary: false, tips: Vec::new() });
        self
    }

    pub fn line(self, name: &str, colour: &'static str, x: &[f64], y: &[f64]) -> Plot {
        self.layer(name, colour, Mark::Line { width: 1 }, x.to_vec(), y.to_vec())
    }

    pub fn points(self, name: &str, colour: &'static str, x: &[f64], y: &[f64]) -> Plot {
        self.layer(name, colour, Mark::Points { radius: 2 }, x.to_vec(), y.to_vec())
    }

    pub fn error_bars(self, name: &str, colour: &'static str, x: &[f64], y: &[f64], half: &[f64]) -> Plot {
        self.layer(name, colour, Mark::ErrorBars { half: half.to_vec() }, x.to_vec(), y.to_vec())
    }

    /// Dashed horizontal levels.
    pub fn levels(self, name: &str, colour: &'static str, y: &[f64]) -> Plot {
        self.layer(name, colour, Mark::Level, vec![f64::NAN; y.len()], y.to_vec())
    }

    /// A layer built by hand (crosses, thicker lines, tips, the secondary axis).
    pub fn with(mut self, l: Layer) -> Plot {
        self.layers.push(l);
        self
    }

    /// The SVG (`<svg class="plot" id="…">…</svg>`).
    pub fn svg(&self) -> String {
        let mut buf = String::new();
        let drawn = draw(self, &mut buf);
        match drawn {
            Ok(tips) => finish(self, buf, &tips),
            Err(e) => error_svg(self, &e),
        }
    }

    /// The axes this plot gets: (x, y, secondary y).
    pub fn axes(&self) -> (Axis, Axis, Axis) {
        let span = |sel: &dyn Fn(&Layer) -> bool, xs: bool| {
            let mut lo = f64::INFINITY;
            let mut hi = f64::NEG_INFINITY;
            for l in self.layers.iter().filter(|l| sel(l)) {
                let half = match &l.mark {
                    Mark::ErrorBars { half } => half.as_slice(),
                    _ => &[],
                };
                let vals: Box<dyn Iterator<Item = f64>> = if xs {
                    Box::new(l.x.iter().copied())
                } else {
                    Box::new(l.y.iter().enumerate().flat_map(move |(i, y)| {
                        let h = half.get(i).copied().filter(|h| h.is_finite()).unwrap_or(0.0);
                        [y - h, y + h]
                    }))
                };
                for v in vals.filter(|v| v.is_finite()) {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (lo, hi)
        };
        let pad = |(lo, hi): (f64, f64)| {
            let p = 0.03 * (hi - lo);
            (lo - p, hi + p)
        };
        let x = self.x_range.unwrap_or_else(|| span(&|l| l.mark != Mark::Level, true));
        let mut y = self.y_range.unwrap_or_else(|| pad(span(&|l| !l.secondary, false)));
        if self.y_zero && self.y_range.is_none() {
            y = (y.0.min(0.0), y.1.max(0.0));
        }
        let y2 = self.y2_range.unwrap_or_else(|| pad(span(&|l| l.secondary, false)));
        let (w, h) = self.size;
        let xt = ((w / 80) as usize).clamp(4, 11);
        let yt = ((h / 45) as usize).clamp(4, 9);
        let ay = if self.y_names.is_empty() {
            Axis::covering(y.0, y.1, yt)
        } else {
            Axis { lo: 0.0, hi: self.y_names.len() as f64 + 1.0, step: 1.0 }
        };
        (Axis::covering(x.0, x.1, xt), ay, Axis::covering(y2.0, y2.1, yt))
    }
}

/// A plotters coordinate whose ticks are the [`Axis`]'s 1-2-5 ticks.
#[derive(Clone)]
struct NiceRange(Axis, Vec<String>);

impl Ranged for NiceRange {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let r = (v - self.0.lo) / (self.0.hi - self.0.lo);
        let px = f64::from(limit.0) + r * f64::from(limit.1 - limit.0);
        // far outside the plot a value still maps to a finite pixel (clipped by the area)
        px.clamp(-1e6, 1e6).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if !self.1.is_empty() {
            (1..=self.1.len()).map(|k| k as f64).collect()
        } else if hint.weight().allow_light_points() {
            self.0.minor_ticks()
        } else {
            self.0.ticks()
        }
    }

    fn range(&self) -> Range<f64> {
        self.0.lo..self.0.hi
    }
}

impl ValueFormatter<f64> for NiceRange {
    fn format(v: &f64) -> String {
        format!("{v}")
    }
    fn format_ext(&self, v: &f64) -> String {
        if self.1.is_empty() {
            self.0.label(*v)
        } else {
            let k = v.round() as usize;
            k.checked_sub(1).and_then(|k| self.1.get(k)).cloned().unwrap_or_default()
        }
    }
}

fn rgb(hex: &str) -> RGBColor {
    let h = hex.trim_start_matches('#');
    let c = |k: usize| h.get(k..k + 2).and_then(|s| u8::from_str_radix(s, 16).ok()).unwrap_or(0);
    RGBColor(c(0), c(2), c(4))
}

type Err = String;

fn e<T: std::fmt::Debug>(x: T) -> Err {
    format!("{x:?}")
}

/// Draws into `buf`; returns the hover targets (pixel x, y, text).
fn draw(p: &Plot, buf: &mut String) -> Result<Vec<(i32, i32, String)>, Err> {
    let (ax, ay, ay2) = p.axes();
    let has2 = p.layers.iter().any(|l| l.secondary);
    let root = SVGBackend::with_string(buf, p.size).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    // plotters writes an SVG font size of size/1.24
    let font = |s: u32| ("sans-serif", f64::from(s) * 1.24).into_font();
    let mut chart = ChartBuilder::on(&root)
        .caption(&p.title, font(15))
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(p.y_names.iter().map(|n| n.chars().count() as u32 * 7 + 24).max().unwrap_or(62).max(62))
        .right_y_label_area_size(if has2 { 62 } else { 8 })
        .build_cartesian_2d(NiceRange(ax.clone(), Vec::new()), NiceRange(ay.clone(), p.y_names.clone()))
        .map_err(e)?
        .set_secondary_coord(NiceRange(ax.clone(), Vec::new()), NiceRange(ay2.clone(), Vec::new()));
    chart
        .configure_mesh()
        .x_desc(&p.x_label)
        .y_desc(&p.y_label)
        .axis_desc_style(font(13))
        .label_style(font(11))
        .bold_line_style(RGBColor(220, 220, 220))
        .light_line_style(RGBColor(244, 244, 244))
        .x_labels(16)
        .y_labels(16)
        .draw()
        .map_err(e)?;
    if has2 {
        chart
            .configure_secondary_axes()
            .y_desc(&p.y2_label)
            .axis_desc_style(font(13))
            .label_style(font(11))
            .draw()
            .map_err(e)?;
    }
    let cols = chart.plotting_area().dim_in_pixel().0 as usize;
    let mut tips = Vec::new();
    let mut legend = false;
    for l in &p.layers {
        let c = rgb(l.colour);
        let (x0, x1) = (ax.lo, ax.hi);
        let to_px = |x: f64, y: f64| {
            let (a, b) = if l.secondary {
                chart.borrow_secondary().backend_coord(&(x, y))
            } else {
                chart.backend_coord(&(x, y))
            };
            (f64::from(a), f64::from(b))
        };
        let pts: Vec<(f64, f64)> = l.x.iter().copied().zip(l.y.iter().copied()).collect();
        for ((x, y), t) in pts.iter().zip(&l.tips) {
            if x.is_finite() && y.is_finite() && !t.is_empty() {
                let (a, b) = to_px(*x, *y);
                tips.push((a as i32, b as i32, t.clone()));
            }
        }
        let elements: Vec<DynElement<SVGBackend, (f64, f64)>> = match &l.mark {
            Mark::Line { width } => {
                let line = if pts.len() > LONG { envelope::m4(&l.x, &l.y, x0, x1, cols) } else { pts.clone() };
                // a break in the data (NaN) breaks the line
                let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                for q in line {
                    if q.0.is_finite() && q.1.is_finite() {
                        if let Some(r) = runs.last_mut() {
                            r.push(q);
                        }
                    } else if runs.last().is_some_and(|r| !r.is_empty()) {
                        runs.push(Vec::new());
                    }
                }
                runs.into_iter().map(|r| PathElement::new(r, c.stroke_width(*width)).into_dyn()).collect()
            }
            Mark::Points { radius } => {
                let fin: Vec<(f64, f64)> =
                    pts.iter().copied().filter(|(a, b)| a.is_finite() && b.is_finite()).collect();
                let shown = if fin.len() > LONG { envelope::pixel_dedupe(&fin, 2.0, to_px) } else { fin };
                let r = if pts.len() > LONG { 1 } else { *radius };
                shown.into_iter().map(|q| Circle::new(q, r, c.mix(0.75).filled()).into_dyn()).collect()
            }
            Mark::Crosses { size } => pts
                .iter()
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .map(|&q| Cross::new(q, *size as i32, c.stroke_width(2)).into_dyn())
                .collect(),
            Mark::ErrorBars { half } => {
                let dx = 0.004 * (x1 - x0);
                let mut v = Vec::new();
                for ((x, y), h) in pts.iter().zip(half) {
                    if !(x.is_finite() && y.is_finite() && h.is_finite()) {
                        continue;
                    }
                    let (lo, hi) = (y - h, y + h);
                    v.push(PathElement::new(vec![(*x, lo), (*x, hi)], c.stroke_width(1)).into_dyn());
                    for yy in [lo, hi] {
                        v.push(PathElement::new(vec![(x - dx, yy), (x + dx, yy)], c.stroke_width(1)).into_dyn());
                    }
                    v.push(Circle::new((*x, *y), 3, c.filled()).into_dyn());
                }
                v
            }
            Mark::Level => {
                l.y.iter()
                    .filter(|y| y.is_finite())
                    .map(|&y| DashedPathElement::new(vec![(x0, y), (x1, y)], 6, 4, c.stroke_width(1)).into_dyn())
                    .collect()
            }
        };
        let anno = if l.secondary {
            chart.draw_secondary_series(elements).map_err(e)?
        } else {
            chart.draw_series(elements).map_err(e)?
        };
        if !l.name.is_empty() {
            legend = true;
            let mark = l.mark.clone();
            anno.label(l.name.as_str()).legend(move |(x, y)| -> DynElement<SVGBackend, (i32, i32)> {
                match mark {
                    Mark::Points { .. } | Mark::ErrorBars { .. } => Circle::new((x + 8, y), 3, c.filled()).into_dyn(),
                    Mark::Crosses { .. } => Cross::new((x + 8, y), 4, c.stroke_width(2)).into_dyn(),
                    Mark::Level => DashedPathElement::new(vec![(x, y), (x + 18, y)], 4, 3, c).into_dyn(),
                    Mark::Line { width } => {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(width)).into_dyn()
                    }
                }
            });
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .position(if p.legend_left { SeriesLabelPosition::UpperLeft } else { SeriesLabelPosition::UpperRight })
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(170, 170, 170))
            .label_font(font(11))
            .draw()
            .map_err(e)?;
    }
    drop(chart);
    root.present().map_err(e)?;
    Ok(tips)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The root `<svg>` gets the class, id and title; hover targets are added last.
fn finish(p: &Plot, buf: String, tips: &[(i32, i32, String)]) -> String {
    let mut attrs = String::from("<svg class=\"plot\"");
    if !p.id.is_empty() {
        let _ = write!(attrs, " id=\"{}\"", esc(&p.id));
    }
    let _ = write!(attrs, " role=\"img\" aria-label=\"{}\" font-family=\"sans-serif\"", esc(&p.title));
    let mut s = buf.replacen("<svg", &attrs, 1);
    if !tips.is_empty() {
        let mut g = String::from("<g class=\"tips\" fill=\"#000\" fill-opacity=\"0\">");
        for (x, y, t) in tips {
            let _ = write!(g, "<circle cx=\"{x}\" cy=\"{y}\" r=\"7\"><title>{}</title></circle>", esc(t));
        }
        g.push_str("</g>\n</svg>");
        if let Some(k) = s.rfind("</svg>") {
            s.replace_range(k.., &g);
        }
    }
    if !s.ends_with('\n') {
        s.push('\n');
    }
    s
}

fn error_svg(p: &Plot, err: &str) -> String {
    let (w, h) = p.size;
    format!(
        "<svg class=\"plot\" id=\"{}\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\"><text x=\"10\" y=\"20\">{}: the plot could not be drawn ({})</text></svg>\n",
        esc(&p.id),
        esc(&p.title),
        esc(err)
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_is_an_svg_with_its_id_labels_and_nice_ticks() {
        let x: Vec<f64> = (0..50).map(|i| 0.091 + i as f64 * (1.959 - 0.091) / 49.0).collect();
        let y: Vec<f64> = x.iter().map(|v| v * v).collect();
        let s = Plot::new("sq", "a square", "q (rad)", "torque (N·m)").points("data", colour::BLUE, &x, &y).svg();
        assert!(s.starts_with("<svg class=\"plot\" id=\"sq\""), "{}", &s[..80]);
        assert!(s.trim_end().ends_with("</svg>"));
        for l in ["q (rad)", "torque (N·m)", "a square", "data", "\n0.5\n", "\n1.5\n"] {
            assert!(s.contains(l), "{l} missing");
        }
        assert!(!s.contains("1.959") && !s.contains("0.091"), "ticks on data values");
        assert_eq!(s.matches("<circle").count(), 50 + 1, "50 points and the legend's");
    }

    #[test]
    fn a_long_line_is_drawn_from_its_envelope() {
        let x: Vec<f64> = (0..120_000).map(|i| i as f64 * 1e-3).collect();
        let y: Vec<f64> = x.iter().map(|t| (t * 7.0).sin()).collect();
        let s = Plot::new("long", "long", "t (s)", "y").line("y", colour::BLACK, &x, &y).svg();
        // ≤ 4 points per pixel column of a 640-pixel plot
        assert!(s.len() < 100_000, "{} bytes", s.len());
    }

    #[test]
    fn tips_and_a_secondary_axis() {
        let s = Plot::new("", "two axes", "F", "RMSE (N·m)")
            .with(Layer {
                name: "osc".into(),
                colour: colour::BROWN,
                mark: Mark::Line { width: 2 },
                x: vec![0.0, 1.0],
                y: vec![10.0, 20.0],
                secondary: true,
                tips: vec!["a".into(), "b <2>".into()],
            })
            .points("rmse", colour::NAVY, &[0.0, 1.0], &[0.1, 0.2])
            .svg();
        assert_eq!(s.matches("<title>").count(), 2);
        assert!(s.contains("b &lt;2&gt;"));
        assert!(s.contains("\n20\n") && s.contains("\n0.2\n"));
    }
}
