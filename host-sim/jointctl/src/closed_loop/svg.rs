//! The fraction-sweep plot: tracking RMSE (mean ± sd over trials) against the compensated
//! fraction F, each point marked stable (filled circle) or unstable (red cross) with its numbers
//! on hover, and the largest oscillation measure on the secondary axis with its threshold.
//! Drawn by `joint_analysis::plot` (plotters), a plain SVG file that opens in any browser.

use joint_analysis::plot::{colour, Layer, Mark, Plot};

use super::{limits, SweepPoint};

fn finite(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        0.0
    }
}

/// Renders the sweep; `title` names plant and delay.
pub fn render(points: &[SweepPoint], title: &str) -> String {
    let f: Vec<f64> = points.iter().map(|p| p.fraction).collect();
    let mean: Vec<f64> = points.iter().map(|p| finite(p.tracking_rmse_mean)).collect();
    let sd: Vec<f64> = points.iter().map(|p| finite(p.tracking_rmse_sd)).collect();
    let osc: Vec<f64> = points.iter().map(|p| finite(p.osc_torque_rms_max)).collect();
    let tip = |p: &SweepPoint| {
        let base = format!("F = {:.2}: {:.3} ± {:.3} N·m", p.fraction, p.tracking_rmse_mean, p.tracking_rmse_sd);
        if p.stable {
            format!("{base}, stable")
        } else {
            format!("{base}, unstable ({:.0} % of trials stable)", 100.0 * p.stable_share)
        }
    };
    let pick = |stable: bool| {
        let set: Vec<&SweepPoint> = points.iter().filter(|p| p.stable == stable).collect();
        (
            set.iter().map(|p| p.fraction).collect::<Vec<f64>>(),
            set.iter().map(|p| finite(p.tracking_rmse_mean)).collect::<Vec<f64>>(),
            set.iter().map(|p| tip(p)).collect::<Vec<String>>(),
        )
    };
    let ((sx, sy, st), (ux, uy, ut)) = (pick(true), pick(false));
    let layer = |name: &str, c: &'static str, mark: Mark, x: Vec<f64>, y: Vec<f64>, secondary: bool, tips| Layer {
        name: name.into(),
        colour: c,
        mark,
        x,
        y,
        secondary,
        tips,
    };
    let mut plot = Plot::new("sweep", title, "compensated fraction F of C_c", "tracking RMSE (N·m), mean ± sd")
        .size(700, 420)
        .with(layer(
            "oscillation above 5 Hz (worst trial)",
            colour::BROWN,
            Mark::Line { width: 1 },
            f.clone(),
            osc,
            true,
            vec![],
        ))
        .with(layer(
            "oscillation threshold",
            colour::BROWN,
            Mark::Level,
            vec![f64::NAN],
            vec![limits::OSC_TORQUE_RMS],
            true,
            vec![],
        ))
        .with(layer("tracking RMSE", colour::NAVY, Mark::Line { width: 2 }, f.clone(), mean.clone(), false, vec![]))
        .error_bars("", colour::NAVY, &f, &mean, &sd)
        .with(layer("stable (all trials)", colour::NAVY, Mark::Points { radius: 4 }, sx, sy, false, st))
        .with(layer("unstable (some trial)", colour::RED, Mark::Crosses { size: 6 }, ux, uy, false, ut));
    plot.y2_label = "oscillation above 5 Hz, N·m RMS (worst trial)".into();
    plot.x_range = Some((0.0, 1.0));
    plot.y_zero = true;
    let top = osc_max(points).max(limits::OSC_TORQUE_RMS * 1.5);
    plot.y2_range = Some((0.0, top));
    plot.svg()
}

fn osc_max(points: &[SweepPoint]) -> f64 {
    points.iter().map(|p| finite(p.osc_torque_rms_max)).fold(0.0, f64::max)
}
