//! The `--report` HTML: one self-contained file (inline CSS and SVG, no script, no network) with
//! the verdict's evidence (the held-out residual binned in the coordinate each named effect lives
//! in, ±2 standard errors, with the fitted correction over it), the residual against velocity,
//! position and time coloured by speed regime, the before/after
//! overlay of measurement and model, the residual's autocorrelation with its 99 % band, and the
//! effect ranking. Every plot is an `<svg class="plot" id="…">` so a test can find it.

use std::fmt::Write as _;

use super::{Diagnosis, PlotData};

const W: f64 = 560.0;
const H: f64 = 260.0;
const M: f64 = 46.0;
const COLOURS: [&str; 3] = ["#1b9e77", "#d95f02", "#7570b3"];
const REGIME_NAMES: [&str; 3] = ["static", "low speed", "high speed"];

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn range(v: &[f64]) -> (f64, f64) {
    let lo = v.iter().copied().filter(|x| x.is_finite()).fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().filter(|x| x.is_finite()).fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    if hi - lo < 1e-12 {
        (lo - 1.0, hi + 1.0)
    } else {
        let pad = 0.04 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

struct Frame {
    x: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        M + (x - self.x.0) / (self.x.1 - self.x.0) * (W - 1.5 * M)
    }
    fn py(&self, y: f64) -> f64 {
        H - M + (y - self.y.0) / (self.y.1 - self.y.0) * -(H - 1.6 * M)
    }
}

fn open(out: &mut String, id: &str, title: &str, xl: &str, yl: &str, f: &Frame) {
    let _ = write!(
        out,
        r##"<figure><svg class="plot" id="{id}" xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" role="img" aria-label="{t}">"##,
        t = esc(title)
    );
    let _ = write!(
        out,
        r##"<rect x="{M}" y="{}" width="{}" height="{}" fill="#fafafa" stroke="#999"/>"##,
        0.6 * M,
        W - 1.5 * M,
        H - 1.6 * M
    );
    for k in 0..=4 {
        let xv = f.x.0 + (f.x.1 - f.x.0) * k as f64 / 4.0;
        let yv = f.y.0 + (f.y.1 - f.y.0) * k as f64 / 4.0;
        let _ = write!(
            out,
            r##"<text x="{:.1}" y="{:.1}" font-size="10" text-anchor="middle">{}</text>"##,
            f.px(xv),
            H - M + 14.0,
            fmt(xv)
        );
        let _ = write!(
            out,
            r##"<text x="{:.1}" y="{:.1}" font-size="10" text-anchor="end">{}</text>"##,
            M - 4.0,
            f.py(yv) + 3.0,
            fmt(yv)
        );
    }
    let _ = write!(
        out,
        r##"<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle">{}</text>"##,
        W / 2.0,
        H - 8.0,
        esc(xl)
    );
    let _ = write!(
        out,
        r##"<text x="12" y="{:.1}" font-size="12" text-anchor="middle" transform="rotate(-90 12 {:.1})">{}</text>"##,
        H / 2.0,
        H / 2.0,
        esc(yl)
    );
    let _ = write!(
        out,
        r##"<text x="{:.1}" y="16" font-size="13" font-weight="bold" text-anchor="middle">{}</text>"##,
        W / 2.0,
        esc(title)
    );
}

fn fmt(v: f64) -> String {
    if v.abs() >= 1000.0 || (v != 0.0 && v.abs() < 0.01) {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

fn scatter(out: &mut String, id: &str, title: &str, xl: &str, x: &[f64], p: &PlotData) {
    let f = Frame { x: range(x), y: range(&p.before) };
    open(out, id, title, xl, &format!("residual ({})", p.unit), &f);
    for (k, c) in COLOURS.iter().enumerate() {
        let _ = write!(out, r##"<g class="regime-{k}" fill="{c}" fill-opacity="0.55">"##);
        for i in 0..x.len() {
            if p.speed_regime[i] as usize == k {
                let _ = write!(out, r##"<circle cx="{:.1}" cy="{:.1}" r="1.6"/>"##, f.px(x[i]), f.py(p.before[i]));
            }
        }
        out.push_str("</g>");
        let _ = write!(
            out,
            r##"<text x="{:.1}" y="{:.1}" font-size="10" fill="{c}">● {}</text>"##,
            W - 1.5 * M - 10.0 + M - 70.0,
            0.6 * M + 12.0 + 12.0 * k as f64,
            REGIME_NAMES[k]
        );
    }
    out.push_str("</svg></figure>\n");
}

/// The verdict's evidence for one effect: binned held-out residual (points, ±2 s.e. bars) and
/// the fitted correction binned the same way (line).
fn evidence_plot(out: &mut String, k: usize, e: &super::evidence::Evidence, unit: &str) {
    let x: Vec<f64> = e.bins.iter().map(|b| b.x).collect();
    let mut ys: Vec<f64> = e.bins.iter().flat_map(|b| [b.residual - 2.0 * b.sem, b.residual + 2.0 * b.sem]).collect();
    ys.extend(e.bins.iter().map(|b| b.fitted));
    ys.push(0.0);
    let f = Frame { x: range(&x), y: range(&ys) };
    let title = format!("evidence for {}: held-out residual binned over {}", e.effect, e.coordinate);
    open(out, &format!("evidence-{k}"), &title, &e.coordinate, &format!("residual ({unit})"), &f);
    let _ = write!(
        out,
        r##"<line x1="{:.1}" x2="{:.1}" y1="{:.1}" y2="{:.1}" stroke="#bbb"/>"##,
        f.px(f.x.0),
        f.px(f.x.1),
        f.py(0.0),
        f.py(0.0)
    );
    out.push_str(r##"<g class="binned-residual" fill="#d95f02" stroke="#d95f02">"##);
    for b in &e.bins {
        let (cx, lo, hi) = (f.px(b.x), f.py(b.residual - 2.0 * b.sem), f.py(b.residual + 2.0 * b.sem));
        let _ = write!(
            out,
            r##"<line x1="{cx:.1}" x2="{cx:.1}" y1="{lo:.1}" y2="{hi:.1}"/><circle cx="{cx:.1}" cy="{:.1}" r="2.2"/>"##,
            f.py(b.residual)
        );
    }
    out.push_str("</g>");
    let fitted: Vec<f64> = e.bins.iter().map(|b| b.fitted).collect();
    polyline(out, &f, &x, &fitted, "#1b9e77", "fitted");
    let _ = write!(
        out,
        r##"<text x="{}" y="30" font-size="10"><tspan fill="#d95f02">● binned residual ±2 s.e.</tspan> <tspan fill="#1b9e77">— fitted {}</tspan></text>"##,
        M + 6.0,
        esc(&e.effect)
    );
    out.push_str("</svg></figure>\n");
}

fn polyline(out: &mut String, f: &Frame, x: &[f64], y: &[f64], colour: &str, class: &str) {
    let _ = write!(out, r##"<polyline class="{class}" fill="none" stroke="{colour}" stroke-width="1" points=""##);
    for (a, b) in x.iter().zip(y) {
        let _ = write!(out, "{:.1},{:.1} ", f.px(*a), f.py(*b));
    }
    out.push_str(r##""/>"##);
}

/// Renders the report.
pub fn render(d: &Diagnosis) -> String {
    let r = &d.report;
    let p = &d.plots;
    let mut o = String::with_capacity(1 << 20);
    o.push_str("<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>jointctl diagnose</title><style>body{font-family:sans-serif;max-width:1200px;margin:1em auto;color:#222}figure{display:inline-block;margin:6px}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#eee}td:first-child{text-align:left}.sig{font-weight:bold;color:#0a0}</style></head><body>\n");
    let _ = writeln!(
        o,
        "<h1>Sim-to-real gap: {} mode</h1><p id=\"verdict\">Verdict: <b>{}</b> — held-out RMSE {} → {} {} (shrink {:.1} %). Noise floor ≈ {} {}. {} samples: {} training, {} held out ({}).</p>",
        r.mode,
        esc(&r.verdict.effects.join(" → ")),
        fmt(r.verdict.holdout_rmse_before),
        fmt(r.verdict.holdout_rmse_after),
        r.gap.unit,
        100.0 * r.verdict.shrink,
        fmt(r.gap.noise_floor),
        r.gap.unit,
        r.samples,
        r.split.train,
        r.split.holdout,
        r.split.method
    );
    if !p.evidence.is_empty() {
        o.push_str("<h2>Evidence for the verdict</h2>\n");
        for (k, e) in p.evidence.iter().enumerate() {
            evidence_plot(&mut o, k, e, p.unit);
        }
    }
    o.push_str("<h2>Where the gap lies</h2>\n");
    scatter(&mut o, "resid-vs-velocity", "residual vs velocity", "qd (rad/s)", &p.qd, p);
    scatter(&mut o, "resid-vs-position", "residual vs position", "q (rad)", &p.q, p);
    scatter(&mut o, "resid-vs-time", "residual vs time", "t (s)", &p.t, p);
    o.push_str(
        "<table id=\"regimes\"><tr><th>regime</th><th>where</th><th>share</th><th>RMSE</th><th>samples</th></tr>",
    );
    for g in &r.regimes {
        let _ = write!(
            o,
            "<tr><td>{}</td><td>{}</td><td>{:.1} %</td><td>{}</td><td>{}</td></tr>",
            esc(&g.name),
            esc(&g.where_),
            100.0 * g.share,
            fmt(g.rmse),
            g.samples
        );
    }
    o.push_str("</table>\n<h2>Before and after</h2>\n");
    // Overlay: measured and both predictions (prediction = measured − residual) over time.
    {
        let pb: Vec<f64> = p.measured.iter().zip(&p.before).map(|(m, r)| m - r).collect();
        let pa: Vec<f64> = p.measured.iter().zip(&p.after).map(|(m, r)| m - r).collect();
        let mut all = p.measured.clone();
        all.extend_from_slice(&pb);
        let f = Frame { x: range(&p.t), y: range(&all) };
        open(&mut o, "overlay", "measured, model before and after", "t (s)", p.measured_label, &f);
        polyline(&mut o, &f, &p.t, &p.measured, "#888", "measured");
        polyline(&mut o, &f, &p.t, &pb, "#d95f02", "before");
        polyline(&mut o, &f, &p.t, &pa, "#1b9e77", "after");
        let _ = write!(
            o,
            r##"<text x="{}" y="30" font-size="10"><tspan fill="#888">measured</tspan> <tspan fill="#d95f02">model</tspan> <tspan fill="#1b9e77">after</tspan></text>"##,
            M + 6.0
        );
        o.push_str("</svg></figure>\n");
        let mut both = p.before.clone();
        both.extend_from_slice(&p.after);
        let f = Frame { x: range(&p.t), y: range(&both) };
        open(
            &mut o,
            "residual-before-after",
            "residual before and after",
            "t (s)",
            &format!("residual ({})", p.unit),
            &f,
        );
        polyline(&mut o, &f, &p.t, &p.before, "#d95f02", "before");
        polyline(&mut o, &f, &p.t, &p.after, "#1b9e77", "after");
        o.push_str("</svg></figure>\n");
    }
    if let Some(res) = &r.resid {
        let c = &res.autocorrelation_before;
        let ca = &res.autocorrelation_after;
        let x: Vec<f64> = c.lags.iter().map(|&l| l as f64).collect();
        let f = Frame { x: range(&x), y: (-1.05, 1.05) };
        open(&mut o, "autocorrelation", "residual autocorrelation (99 % band)", "lag (samples)", "correlation", &f);
        for b in [c.band99, -c.band99] {
            let _ = write!(
                o,
                r##"<line x1="{:.1}" x2="{:.1}" y1="{:.1}" y2="{:.1}" stroke="#c00" stroke-dasharray="4 3"/>"##,
                f.px(f.x.0),
                f.px(f.x.1),
                f.py(b),
                f.py(b)
            );
        }
        polyline(&mut o, &f, &x, &c.values, "#d95f02", "before");
        polyline(&mut o, &f, &x, &ca.values, "#1b9e77", "after");
        o.push_str("</svg></figure>\n");
        if let Some(xc) = res.xcorr_before.first() {
            let x: Vec<f64> = xc.lags.iter().map(|&l| l as f64).collect();
            let f = Frame { x: range(&x), y: (-1.05, 1.05) };
            open(
                &mut o,
                "crosscorrelation",
                &format!("residual × {} cross-correlation", res.input.first().unwrap_or(&"input")),
                "lag (samples)",
                "correlation",
                &f,
            );
            for b in [xc.band99, -xc.band99] {
                let _ = write!(
                    o,
                    r##"<line x1="{:.1}" x2="{:.1}" y1="{:.1}" y2="{:.1}" stroke="#c00" stroke-dasharray="4 3"/>"##,
                    f.px(f.x.0),
                    f.px(f.x.1),
                    f.py(b),
                    f.py(b)
                );
            }
            polyline(&mut o, &f, &x, &xc.values, "#d95f02", "before");
            if let Some(xa) = res.xcorr_after.first() {
                polyline(&mut o, &f, &x, &xa.values, "#1b9e77", "after");
            }
            o.push_str("</svg></figure>\n");
        }
    }
    o.push_str("<h2>Effect ranking (held-out)</h2>\n");
    {
        let n = r.effects.len().max(1) as f64;
        let hh = 24.0 + 18.0 * n;
        let max = r.effects.iter().map(|e| e.holdout_rmse_before.max(e.holdout_rmse_after)).fold(1e-12, f64::max);
        let _ = write!(
            o,
            r##"<figure><svg class="plot" id="ranking" xmlns="http://www.w3.org/2000/svg" width="{W}" height="{hh}" viewBox="0 0 {W} {hh}">"##
        );
        for (k, e) in r.effects.iter().enumerate() {
            let y = 12.0 + 18.0 * k as f64;
            let wb = (W - 200.0) * e.holdout_rmse_before / max;
            let wa = (W - 200.0) * e.holdout_rmse_after / max;
            let col = if e.significant { "#1b9e77" } else { "#bbb" };
            let _ = write!(
                o,
                r##"<text x="170" y="{:.1}" font-size="11" text-anchor="end">{}</text>"##,
                y + 11.0,
                esc(&e.effect)
            );
            let _ = write!(o, r##"<rect x="176" y="{y:.1}" width="{wb:.1}" height="14" fill="#eee" stroke="#ccc"/>"##);
            let _ = write!(
                o,
                r##"<rect class="bar" x="176" y="{:.1}" width="{wa:.1}" height="10" fill="{col}"/>"##,
                y + 2.0
            );
        }
        o.push_str("</svg></figure>\n");
    }
    o.push_str("<table id=\"effects\"><tr><th>effect</th><th>held-out RMSE before</th><th>after</th><th>shrink</th><th>p</th><th>significant</th><th>parameters</th></tr>");
    for e in &r.effects {
        let params: Vec<String> = e.params.iter().map(|(k, v)| format!("{k} = {}", fmt(*v))).collect();
        let _ = write!(
            o,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.1} %</td><td>{:.2e}</td><td class=\"{}\">{}</td><td>{}</td></tr>",
            esc(&e.effect),
            fmt(e.holdout_rmse_before),
            fmt(e.holdout_rmse_after),
            100.0 * e.shrink,
            e.p_value,
            if e.significant { "sig" } else { "" },
            if e.significant { "yes" } else { "no" },
            esc(&params.join(", "))
        );
    }
    let _ = write!(o, "</table>\n<p>Test: {}.</p></body></html>\n", esc(r.test.method));
    o
}
