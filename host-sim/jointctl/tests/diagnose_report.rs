//! The `--report` HTML opens offline in a real browser: headless Chromium (Debian package
//! `chromium`, installed by scripts/chromium.sh) parses it, the DOM it builds holds every plot
//! with its points and curves, its inline script builds the zoomable views (canvases it draws,
//! the figures marked ready), and a screenshot of it is not blank. The page names no URL and
//! loads nothing: the only script is inline. Skips with a message when no Chromium is installed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use std::process::Command;

use host_sim::plant::PlantFile;
use host_sim::scenario::ScenarioKind;
use host_sim::sim::{simulate, SimConfig};
use joint_formats::model_file::ModelFile;

const MODEL: &str = "[friction]\na = 0.5\nb = 2.0\nc = 1.0\nv_band = 0.01\n[weight]\namplitude = 2.5\ns = 0.802\n[inertia]\nj = 0.4\n[offset]\nc0 = -0.3\n";

fn chromium() -> Option<String> {
    for c in ["chromium", "chromium-browser"] {
        if Command::new(c).arg("--version").output().map(|o| o.status.success()).unwrap_or(false) {
            return Some(c.to_string());
        }
    }
    None
}

#[test]
fn report_renders_in_headless_chromium_with_all_plots() {
    let dir = tempfile::tempdir().unwrap();
    let plant = PlantFile::parse(
        &format!("{MODEL}[position_ripple]\namplitude = 0.4\nperiod = 0.05\n[sensors]\ntau_noise = 0.05\nqdd_noise = 0.2\n[joint_range]\nmin = 0.0\nmax = 2.0\n"),
        "p",
    )
    .unwrap();
    let model = ModelFile::parse(MODEL, "m").unwrap();
    let cfg = SimConfig {
        scenarios: vec![ScenarioKind::Sweep, ScenarioKind::Hand],
        seconds: 6.0,
        rate: Some(1000.0),
        ..SimConfig::default()
    };
    let (log, _) = simulate(&plant, &model.param_set().unwrap(), &cfg).unwrap();
    let (l, m, html) = (dir.path().join("l.csv"), dir.path().join("m.toml"), dir.path().join("report.html"));
    log.write_file(&l).unwrap();
    std::fs::write(&m, MODEL).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_jointctl"))
        .args([
            "diagnose",
            "--log",
            l.to_str().unwrap(),
            "--model",
            m.to_str().unwrap(),
            "--report",
            html.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&html).unwrap();
    // Self-contained: nothing is fetched. The only URLs are SVG namespaces; scripts are inline
    // (no src=, no import, no fetch), styles too (no <link>, no @import, no url(...)).
    assert_eq!(
        text.matches("http://").count(),
        text.matches("xmlns=\"http://www.w3.org/2000/svg\"").count(),
        "only SVG namespaces may name a URL"
    );
    for banned in ["https://", "src=", "<link", "@import", "url(", "import(", "fetch(", "XMLHttpRequest", "//cdn"] {
        assert!(!text.contains(banned), "the report names {banned}");
    }
    assert_eq!(text.matches("<script>").count(), 1, "one inline viewer script");
    assert_eq!(text.matches("<script").count(), 1 + text.matches("<script type=\"application/json\"").count());
    assert!(text.matches("<figure class=\"iv\"").count() >= 2, "the time series are zoomable");
    let Some(browser) = chromium() else {
        eprintln!(
            "SKIPPED: no `chromium` on this machine (run scripts/chromium.sh); the HTML was checked as text only"
        );
        return;
    };
    let url = format!("file://{}", html.display());
    let common =
        ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking", "--hide-scrollbars"];
    let dom =
        Command::new(&browser).args(common).args(["--virtual-time-budget=5000", "--dump-dom", &url]).output().unwrap();
    assert!(dom.status.success(), "{}", String::from_utf8_lossy(&dom.stderr));
    let dom = String::from_utf8_lossy(&dom.stdout);
    for id in [
        "resid-vs-velocity",
        "resid-vs-position",
        "resid-vs-time",
        "overlay",
        "residual-before-after",
        "autocorrelation",
        "crosscorrelation",
        "ranking",
        "evidence-0",
    ] {
        assert!(dom.contains(&format!("<svg class=\"plot\" id=\"{id}\"")), "plot {id} missing from the rendered DOM");
    }
    // 6 s at 1 kHz: every sample is in the plot data; the scatters keep one point per pixel
    // cell, the lines their per-column envelope
    assert!(dom.matches("<circle").count() > 3 * 500, "scatter points missing");
    assert!(dom.matches("<polyline").count() >= 6, "curves missing");
    assert!(dom.contains("id=\"verdict\"") && dom.contains("position_ripple"));
    // the verdict's evidence lives in its own coordinate: a ripple over its phase q mod P, with
    // the fitted curve drawn over the binned residual
    assert!(
        dom.contains("evidence for position_ripple: held-out residual binned over q mod P (rad), P = 0.05"),
        "the evidence plot does not name the ripple's coordinate"
    );
    assert!(dom.contains("fitted position_ripple") && dom.contains("binned residual ± 2 s.e."));
    // The script ran: each zoomable figure got a canvas it drew lines on, and the static SVG is
    // hidden behind it (still in the page).
    let ready = dom.matches("data-iv=\"ready\"").count();
    assert!(
        ready >= 2,
        "the zoomable views were not built ({ready} ready); DOM has data-iv={:?}",
        dom.find("data-iv=")
    );
    assert!(!dom.contains("data-iv=\"error"), "the viewer failed");
    assert_eq!(dom.matches("<canvas class=\"iv-canvas\"").count(), ready);
    for drawn in dom.split("data-iv-drawn=\"").skip(1) {
        let n: usize = drawn.split('"').next().unwrap().parse().unwrap();
        assert!(n > 500, "a zoomable view drew only {n} points");
    }
    let png = dir.path().join("shot.png");
    let shot = Command::new(&browser)
        .args(common)
        .args([
            "--window-size=1200,2400",
            "--virtual-time-budget=5000",
            &format!("--screenshot={}", png.display()),
            &url,
        ])
        .output()
        .unwrap();
    assert!(shot.status.success(), "{}", String::from_utf8_lossy(&shot.stderr));
    // A blank 1200×2400 page compresses to a few kB; the plots make it far larger.
    let size = std::fs::metadata(&png).unwrap().len();
    assert!(size > 100_000, "screenshot only {size} bytes");
}
