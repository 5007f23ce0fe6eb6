//! The zoomable view of a long plot in an HTML report, offline: the plot's lines go into the
//! page as JSON min/max pyramids ([`super::envelope::pyramid`]), and one inline script draws
//! them on a canvas at the level of detail the zoom needs — wheel to zoom the x axis around the
//! cursor, drag to pan, shift-drag to zoom to a box, double-click to go back. Nothing is
//! fetched (no CDN, no `src=`). Without script the static SVG stays: the script hides it only
//! once its own view has been drawn, and marks the figure `data-iv="ready"`.

use std::fmt::Write as _;

use super::{envelope, Mark, Plot};

/// A value for the page's JSON: f32 precision (the shortest text that reads back as the same
/// f32 — a screen has fewer pixels than that), `null` when not finite.
fn num(out: &mut String, v: f64) {
    if v.is_finite() {
        let _ = write!(out, "{}", v as f32);
    } else {
        out.push_str("null");
    }
}

/// Steps of the x quantum over the plot's x range (2²⁴: 1/8000 of a pixel at 2000 px).
const X_STEPS: f64 = 16_777_216.0;
/// Steps of the y quantum over a line's y range (60 000: 1/30 of a pixel at 2000 px).
const Y_STEPS: f64 = 60_000.0;

/// x values as integer steps of `q` from `x0`, each written as the difference to the one
/// before (a log's uniform steps become one short number each); the viewer sums them back.
/// A 180 k-sample log's page was 27 MB with every value written out.
fn x_deltas(out: &mut String, v: &[f64], x0: f64, q: f64) {
    out.push('[');
    let mut prev: i64 = 0;
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let k = ((x - x0) / q).round() as i64;
        let _ = write!(out, "{}", k - prev);
        prev = k;
    }
    out.push(']');
}

/// y values as integer steps of `q` from `y0`, `null` when not finite.
fn y_steps(out: &mut String, v: &[f64], y0: f64, q: f64) {
    out.push('[');
    for (i, y) in v.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        if y.is_finite() {
            let _ = write!(out, "{}", ((y - y0) / q).round() as i64);
        } else {
            out.push_str("null");
        }
    }
    out.push(']');
}

/// A JSON string that cannot close the `<script>` it sits in.
fn string(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into()).replace("</", "<\\/")
}

/// The JSON the viewer reads: the plot's size, labels, full x range, and each line layer as a
/// pyramid (level 0 the samples, each further level buckets of four of the one before), its
/// values as integer steps (x: `xq` = [origin, quantum], differences to the previous value;
/// y: the line's `yq`), which the viewer turns back into numbers once, when the page loads.
pub fn data_json(p: &Plot) -> String {
    let (ax, _, _) = p.axes();
    let mut o = String::new();
    let _ = write!(
        o,
        "{{\"w\":{},\"h\":{},\"title\":{},\"xl\":{},\"yl\":{},\"x0\":",
        p.size.0,
        p.size.1,
        string(&p.title),
        string(&p.x_label),
        string(&p.y_label)
    );
    num(&mut o, ax.lo);
    o.push_str(",\"x1\":");
    num(&mut o, ax.hi);
    let xq = ((ax.hi - ax.lo) / X_STEPS).max(f64::MIN_POSITIVE);
    o.push_str(",\"xq\":[");
    num(&mut o, ax.lo);
    o.push(',');
    let _ = write!(o, "{xq:e}");
    o.push_str("],\"series\":[");
    let lines = p.layers.iter().filter(|l| matches!(l.mark, Mark::Line { .. }) && !l.secondary);
    for (k, l) in lines.enumerate() {
        if k > 0 {
            o.push(',');
        }
        let (y0, y1) =
            l.y.iter()
                .filter(|y| y.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
        let (y0, y1) = if y0 <= y1 { (y0, y1) } else { (0.0, 1.0) };
        let yq = ((y1 - y0) / Y_STEPS).max(f64::MIN_POSITIVE);
        let _ = write!(
            o,
            "{{\"name\":{},\"colour\":{},\"yq\":[{y0:e},{yq:e}],\"levels\":[",
            string(&l.name),
            string(l.colour)
        );
        for (j, lev) in envelope::pyramid(&l.x, &l.y, 256).iter().enumerate() {
            if j > 0 {
                o.push(',');
            }
            let _ = write!(o, "{{\"b\":{},\"x\":", lev.bucket);
            x_deltas(&mut o, &lev.x, ax.lo, xq);
            o.push_str(",\"lo\":");
            y_steps(&mut o, &lev.lo, y0, yq);
            if lev.bucket > 1 {
                o.push_str(",\"hi\":");
                y_steps(&mut o, &lev.hi, y0, yq);
            }
            o.push('}');
        }
        o.push_str("]}");
    }
    o.push_str("]}");
    o
}

/// The figure: the static SVG, the data for the zoomable view, and a caption.
pub fn figure(p: &Plot) -> String {
    format!(
        "<figure class=\"iv\" data-iv=\"static\">{}<script type=\"application/json\" class=\"iv-data\">{}</script></figure>\n",
        p.svg(),
        data_json(p)
    )
}

/// The viewer, once per page, after the figures.
pub const SCRIPT: &str = concat!("<script>\n", include_str!("viewer.js"), "</script>\n");

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::plot::colour;

    #[test]
    fn the_data_is_valid_json_with_a_pyramid_per_line() {
        let x: Vec<f64> = (0..10_000).map(|i| f64::from(i) * 1e-3).collect();
        let y: Vec<f64> = x.iter().map(|t| t.sin()).collect();
        let p = Plot::new("a", "t </script>", "t (s)", "y").line("y", colour::BLACK, &x, &y);
        let j = data_json(&p);
        assert!(!j.contains("</"), "the JSON could close its script");
        let v: serde_json::Value = serde_json::from_str(&j).unwrap();
        let lv = v["series"][0]["levels"].as_array().unwrap();
        assert_eq!(lv[0]["x"].as_array().unwrap().len(), 10_000);
        // the values come back from their steps to well under a pixel
        let xq = v["xq"][1].as_f64().unwrap();
        let mut acc = 0i64;
        for (i, dx) in lv[0]["x"].as_array().unwrap().iter().enumerate() {
            acc += dx.as_i64().unwrap();
            assert!((v["xq"][0].as_f64().unwrap() + acc as f64 * xq - x[i]).abs() < 1e-6, "x[{i}]");
        }
        let (y0, yq) = (v["series"][0]["yq"][0].as_f64().unwrap(), v["series"][0]["yq"][1].as_f64().unwrap());
        for (i, k) in lv[0]["lo"].as_array().unwrap().iter().enumerate() {
            assert!((y0 + k.as_f64().unwrap() * yq - y[i]).abs() <= 0.51 * yq, "y[{i}]");
        }
        assert_eq!(lv[1]["b"], 4);
        assert_eq!(lv[1]["hi"].as_array().unwrap().len(), 2500);
        assert_eq!(v["x0"], 0.0);
        let f = figure(&p);
        assert!(f.contains("<svg class=\"plot\" id=\"a\"") && !f.contains("src="));
        assert!(!SCRIPT.contains("src=") && !SCRIPT.contains("http"));
    }
}
