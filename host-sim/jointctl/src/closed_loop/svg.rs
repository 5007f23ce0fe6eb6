//! The fraction-sweep plot: tracking RMSE (mean ± sd over trials) against the compensated
//! fraction F, each point marked stable (filled circle) or unstable (red cross), and the
//! largest oscillation measure on a second axis. Hand-written SVG, no dependencies, so the
//! file opens in any browser and diffs as text.

use std::fmt::Write as _;

use super::{limits, SweepPoint};

const W: f64 = 640.0;
const H: f64 = 400.0;
const L: f64 = 70.0;
const R: f64 = 70.0;
const T: f64 = 40.0;
const B: f64 = 60.0;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A "nice" upper bound for an axis holding values up to `v`.
fn nice_max(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return 1.0;
    }
    let e = 10f64.powf(v.log10().floor());
    for m in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if m * e >= v {
            return m * e;
        }
    }
    10.0 * e
}

/// Renders the sweep; `title` names plant and delay.
pub fn render(points: &[SweepPoint], title: &str) -> String {
    let finite = |x: f64| if x.is_finite() { x } else { 0.0 };
    let y1_max =
        nice_max(points.iter().map(|p| finite(p.tracking_rmse_mean) + finite(p.tracking_rmse_sd)).fold(0.0, f64::max));
    let y2_max =
        nice_max(points.iter().map(|p| finite(p.osc_torque_rms_max)).fold(limits::OSC_TORQUE_RMS * 1.5, f64::max));
    let pw = W - L - R;
    let ph = H - T - B;
    let x = |f: f64| L + f.clamp(0.0, 1.0) * pw;
    let y1 = |v: f64| T + ph * (1.0 - (v / y1_max).clamp(0.0, 1.05));
    let y2 = |v: f64| T + ph * (1.0 - (v / y2_max).clamp(0.0, 1.05));
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    let _ = writeln!(s, r#"<text x="{}" y="22" text-anchor="middle" font-size="14">{}</text>"#, W / 2.0, esc(title));
    // axes and grid
    for i in 0..=5 {
        let v = y1_max * i as f64 / 5.0;
        let yy = y1(v);
        let _ = writeln!(s, r##"<line x1="{L}" y1="{yy:.1}" x2="{:.1}" y2="{yy:.1}" stroke="#ddd"/>"##, L + pw);
        let _ = writeln!(s, r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{v:.2}</text>"#, L - 6.0, yy + 4.0);
        let v2 = y2_max * i as f64 / 5.0;
        let _ = writeln!(s, r##"<text x="{:.1}" y="{:.1}" fill="#a60">{v2:.2}</text>"##, L + pw + 6.0, y2(v2) + 4.0);
    }
    for i in 0..=10 {
        let f = i as f64 / 10.0;
        let _ = writeln!(s, r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{f:.1}</text>"#, x(f), T + ph + 18.0);
    }
    let _ = writeln!(s, r#"<rect x="{L}" y="{T}" width="{pw}" height="{ph}" fill="none" stroke="black"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">compensated fraction F of C_c</text>"#,
        L + pw / 2.0,
        H - 18.0
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate(18 {:.1}) rotate(-90)" text-anchor="middle">tracking RMSE, N·m (mean ± sd)</text>"#,
        T + ph / 2.0
    );
    let _ = writeln!(
        s,
        r##"<text transform="translate({:.1} {:.1}) rotate(90)" text-anchor="middle" fill="#a60">oscillation above 5 Hz, N·m RMS (worst trial)</text>"##,
        W - 14.0,
        T + ph / 2.0
    );
    // oscillation threshold and curve
    let _ = writeln!(
        s,
        r##"<line x1="{L}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#a60" stroke-dasharray="4 3"/>"##,
        L + pw,
        y = y2(limits::OSC_TORQUE_RMS)
    );
    let osc: Vec<String> =
        points.iter().map(|p| format!("{:.1},{:.1}", x(p.fraction), y2(finite(p.osc_torque_rms_max)))).collect();
    let _ = writeln!(s, r##"<polyline points="{}" fill="none" stroke="#a60" stroke-width="1.5"/>"##, osc.join(" "));
    // RMSE curve with error bars
    let line: Vec<String> = points
        .iter()
        .filter(|p| p.tracking_rmse_mean.is_finite())
        .map(|p| format!("{:.1},{:.1}", x(p.fraction), y1(p.tracking_rmse_mean)))
        .collect();
    let _ = writeln!(s, r##"<polyline points="{}" fill="none" stroke="#236" stroke-width="2"/>"##, line.join(" "));
    for p in points {
        let (cx, m, sd) = (x(p.fraction), finite(p.tracking_rmse_mean), finite(p.tracking_rmse_sd));
        let _ = writeln!(
            s,
            r##"<line x1="{cx:.1}" y1="{:.1}" x2="{cx:.1}" y2="{:.1}" stroke="#236"/>"##,
            y1(m - sd),
            y1(m + sd)
        );
        if p.stable {
            let _ = writeln!(
                s,
                r##"<circle cx="{cx:.1}" cy="{:.1}" r="4.5" fill="#236"><title>F = {:.2}: {:.3} ± {:.3} N·m, stable</title></circle>"##,
                y1(m),
                p.fraction,
                m,
                sd
            );
        } else {
            let cy = y1(m);
            let _ = writeln!(
                s,
                r##"<path d="M{:.1},{:.1} l10,10 m0,-10 l-10,10" stroke="#c00" stroke-width="2.5"><title>F = {:.2}: {:.3} ± {:.3} N·m, unstable ({:.0} % of trials stable)</title></path>"##,
                cx - 5.0,
                cy - 5.0,
                p.fraction,
                m,
                sd,
                100.0 * p.stable_share
            );
        }
    }
    // legend
    let lx = L + 10.0;
    let _ = writeln!(
        s,
        r##"<circle cx="{:.1}" cy="{:.1}" r="4.5" fill="#236"/><text x="{:.1}" y="{:.1}">stable (all trials)</text>"##,
        lx + 5.0,
        T + 14.0,
        lx + 16.0,
        T + 18.0
    );
    let _ = writeln!(
        s,
        r##"<path d="M{:.1},{:.1} l10,10 m0,-10 l-10,10" stroke="#c00" stroke-width="2.5"/><text x="{:.1}" y="{:.1}">unstable (some trial)</text>"##,
        lx,
        T + 27.0,
        lx + 16.0,
        T + 36.0
    );
    let _ = writeln!(
        s,
        r##"<line x1="{lx:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#a60" stroke-dasharray="4 3"/><text x="{:.1}" y="{:.1}">oscillation threshold</text>"##,
        T + 50.0,
        lx + 12.0,
        T + 50.0,
        lx + 16.0,
        T + 54.0
    );
    s.push_str("</svg>\n");
    s
}
