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

fn array(out: &mut String, v: &[f64]) {
    out.push('[');
    for (i, x) in v.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        num(out, *x);
    }
    out.push(']');
}

/// A JSON string that cannot close the `<script>` it sits in.
fn string(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into()).replace("</", "<\\/")
}

/// The JSON the viewer reads: the plot's size, labels, full x range, and each line layer as a
/// pyramid (level 0 the samples, each further level buckets of four of the one before).
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
    o.push_str(",\"series\":[");
    let lines = p.layers.iter().filter(|l| matches!(l.mark, Mark::Line { .. }) && !l.secondary);
    for (k, l) in lines.enumerate() {
        if k > 0 {
            o.push(',');
        }
        let _ = write!(o, "{{\"name\":{},\"colour\":{},\"levels\":[", string(&l.name), string(l.colour));
        for (j, lev) in envelope::pyramid(&l.x, &l.y, 256).iter().enumerate() {
            if j > 0 {
                o.push(',');
            }
            let _ = write!(o, "{{\"b\":{},\"x\":", lev.bucket);
            array(&mut o, &lev.x);
            o.push_str(",\"lo\":");
            array(&mut o, &lev.lo);
            if lev.bucket > 1 {
                o.push_str(",\"hi\":");
                array(&mut o, &lev.hi);
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
        assert_eq!(lv[1]["b"], 4);
        assert_eq!(lv[1]["hi"].as_array().unwrap().len(), 2500);
        assert_eq!(v["x0"], 0.0);
        let f = figure(&p);
        assert!(f.contains("<svg class=\"plot\" id=\"a\"") && !f.contains("src="));
        assert!(!SCRIPT.contains("src=") && !SCRIPT.contains("http"));
    }
}
