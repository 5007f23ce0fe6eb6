//! `diag-bench run`: runs `jointctl diagnose` as a black box on every case and scores its
//! verdicts against truth.json.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use anyhow::Context;
use serde::Serialize;
use serde_json::{json, Value};

/// One case to run.
#[derive(Debug, Clone)]
struct Job {
    dir: PathBuf,
    seed: u64,
    seed_class: String,
    truth: Value,
}

/// How a case ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Correct,
    /// Truth `none`, verdict anything else.
    OverClaim,
    /// Not correct, but `unexplained` or the truth among the alternatives.
    Unsure,
    Wrong,
    /// The tool exited non-zero or wrote no readable verdict.
    Refused,
}

#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    pub dir: String,
    pub seed: u64,
    pub seed_class: String,
    pub mode: String,
    pub label: String,
    pub truth: Vec<String>,
    /// drawn effects the log does not show (below [`SHOWN_SNR`] in a compound): optional
    pub optional: Vec<String>,
    /// right with every drawn effect required (the optional ones too)
    pub strict_correct: bool,
    pub trajectory_family: String,
    pub rate_hz: f64,
    pub rate_band: String,
    pub snr: f64,
    pub detectable_hint: bool,
    pub exit_code: Option<i32>,
    pub stderr_tail: String,
    pub seconds: f64,
    pub verdict: Option<String>,
    pub reported: Vec<String>,
    pub alternatives: Vec<String>,
    pub outcome: Outcome,
}

/// Options of `run`.
pub struct RunOpts {
    pub cases_dirs: Vec<PathBuf>,
    pub jointctl: PathBuf,
    pub json_out: Option<PathBuf>,
    pub jobs: usize,
    pub timeout: Duration,
}

fn load_jobs(dir: &Path) -> anyhow::Result<Vec<Job>> {
    let text = std::fs::read_to_string(dir.join("manifest.json"))
        .with_context(|| format!("reading {}/manifest.json", dir.display()))?;
    let m: Value = serde_json::from_str(&text)?;
    let seed = at(&m, "seed").as_u64().unwrap_or(0);
    let class = at(&m, "seed_class").as_str().unwrap_or("other").to_string();
    let mut jobs = Vec::new();
    for c in at(&m, "cases").as_array().into_iter().flatten() {
        let name = at(c, "dir").as_str().context("manifest case without dir")?;
        let cdir = dir.join(name);
        let truth: Value = serde_json::from_str(&std::fs::read_to_string(cdir.join("truth.json"))?)?;
        jobs.push(Job { dir: cdir, seed, seed_class: class.clone(), truth });
    }
    Ok(jobs)
}

/// A field of a JSON object, Null when absent (no panicking index).
fn at<'a>(v: &'a Value, key: &str) -> &'a Value {
    static NULL: Value = Value::Null;
    v.get(key).unwrap_or(&NULL)
}

/// Names from a list whose items are strings or objects with an "effect" key.
fn names(v: &Value) -> Vec<String> {
    v.as_array()
        .into_iter()
        .flatten()
        .filter_map(|x| x.as_str().or_else(|| at(x, "effect").as_str()).map(str::to_string))
        .collect()
}

pub fn rate_band(rate: f64) -> &'static str {
    if rate < 100.0 {
        "<100 Hz"
    } else if rate < 300.0 {
        "100-300 Hz"
    } else if rate < 1000.0 {
        "300-1000 Hz"
    } else {
        ">=1000 Hz"
    }
}

/// A drawn effect of a compound whose own SNR (`snr_per_effect`) stays below this could not be
/// sized into the band the generator draws in (its range ends first, see the README's sizing
/// paragraph): its deviation is a fraction of the noise, and the label asks the log for
/// something it does not show. It is optional in scoring: a verdict may name it or not.
pub const SHOWN_SNR: f64 = 0.5;

/// The effects of a compound truth that are optional in scoring (see [`SHOWN_SNR`]): below it,
/// while another drawn effect is at or above it.
pub fn optional_effects(truth: &[String], snr_per_effect: &Value) -> Vec<String> {
    let snr = |e: &String| at(snr_per_effect, e).as_f64();
    if truth.len() < 2 || !truth.iter().any(|e| snr(e).is_some_and(|x| x >= SHOWN_SNR)) {
        return Vec::new();
    }
    truth.iter().filter(|e| snr(e).is_some_and(|x| x < SHOWN_SNR)).cloned().collect()
}

/// Scores one verdict against the truth set (every drawn effect required).
pub fn classify(truth: &[String], verdict: Option<&Value>) -> (Outcome, Option<String>, Vec<String>, Vec<String>) {
    classify_shown(truth, &[], verdict)
}

/// Scores one verdict against the truth set, where the `optional` ones among it may be named
/// or not (correct: every other drawn effect named, and nothing outside the truth).
pub fn classify_shown(
    truth: &[String],
    optional: &[String],
    verdict: Option<&Value>,
) -> (Outcome, Option<String>, Vec<String>, Vec<String>) {
    let Some(v) = verdict else {
        return (Outcome::Refused, None, Vec::new(), Vec::new());
    };
    let Some(effect) = at(v, "effect").as_str() else {
        return (Outcome::Refused, None, Vec::new(), Vec::new());
    };
    let mut reported = names(at(v, "effects"));
    if reported.is_empty() {
        reported = vec![effect.to_string()];
    }
    let alternatives = names(at(v, "alternatives"));
    let want: BTreeSet<&str> = truth.iter().map(String::as_str).collect();
    let got: BTreeSet<&str> = reported.iter().map(String::as_str).collect();
    let truth_none = want.len() == 1 && want.contains("none");
    let required: BTreeSet<&str> = want.iter().copied().filter(|e| !optional.iter().any(|o| o == e)).collect();
    let outcome = if want == got || (!required.is_empty() && got.is_subset(&want) && required.is_subset(&got)) {
        Outcome::Correct
    } else if truth_none {
        Outcome::OverClaim
    } else if effect == "unexplained" || truth.iter().any(|t| alternatives.contains(t)) {
        Outcome::Unsure
    } else {
        Outcome::Wrong
    };
    (outcome, Some(effect.to_string()), reported, alternatives)
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines.iter().skip(lines.len().saturating_sub(n)).copied().collect::<Vec<_>>().join("\n")
}

fn run_one(job: &Job, opts: &RunOpts) -> anyhow::Result<CaseResult> {
    let result_path = job.dir.join("result.json");
    let _ = std::fs::remove_file(&result_path);
    let stderr_path = job.dir.join("diagnose.stderr");
    let stderr_file = std::fs::File::create(&stderr_path)?;
    let start = Instant::now();
    let mut child = Command::new(&opts.jointctl)
        .arg("diagnose")
        .arg("--log")
        .arg(job.dir.join("log.csv"))
        .arg("--model")
        .arg(job.dir.join("model.toml"))
        .arg("--json")
        .arg(&result_path)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(stderr_file)
        .spawn()
        .with_context(|| format!("starting {}", opts.jointctl.display()))?;
    // Polling rather than wait(): a case that hangs is killed (our own child) and scored
    // as refused instead of stalling the whole run.
    let status = loop {
        if let Some(s) = child.try_wait()? {
            break Some(s);
        }
        if start.elapsed() > opts.timeout {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let seconds = start.elapsed().as_secs_f64();
    let mut stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    if status.is_none() {
        stderr.push_str(&format!("\n[diag-bench] killed after {:.0} s timeout", opts.timeout.as_secs_f64()));
    }
    let exit_code = status.and_then(|s| s.code());
    let ok = status.is_some_and(|s| s.success());
    let report: Option<Value> =
        if ok { std::fs::read_to_string(&result_path).ok().and_then(|t| serde_json::from_str(&t).ok()) } else { None };
    let truth_set = names(at(&job.truth, "effects"));
    let optional = optional_effects(&truth_set, at(&job.truth, "snr_per_effect"));
    let verdict_json = report.as_ref().map(|r| at(r, "verdict"));
    let (outcome, verdict, reported, alternatives) = classify_shown(&truth_set, &optional, verdict_json);
    let strict_correct = classify(&truth_set, verdict_json).0 == Outcome::Correct;
    let rate = at(&job.truth, "rate_hz").as_f64().unwrap_or(0.0);
    Ok(CaseResult {
        dir: job.dir.display().to_string(),
        seed: job.seed,
        seed_class: job.seed_class.clone(),
        mode: at(&job.truth, "mode").as_str().unwrap_or("?").to_string(),
        label: at(&job.truth, "label").as_str().unwrap_or("?").to_string(),
        truth: truth_set,
        optional,
        strict_correct,
        trajectory_family: at(&job.truth, "trajectory_family").as_str().unwrap_or("?").to_string(),
        rate_hz: rate,
        rate_band: rate_band(rate).to_string(),
        snr: at(&job.truth, "snr").as_f64().unwrap_or(0.0),
        detectable_hint: at(&job.truth, "detectable_hint").as_bool().unwrap_or(false),
        exit_code,
        stderr_tail: tail(&stderr, 5),
        seconds,
        verdict,
        reported,
        alternatives,
        outcome,
    })
}

/// Runs every case with `jobs` workers and returns the results in case order.
fn run_all(jobs: &[Job], opts: &RunOpts) -> anyhow::Result<Vec<CaseResult>> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, CaseResult)>> = Mutex::new(Vec::new());
    let errors: Mutex<Vec<String>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.max(1) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(job) = jobs.get(i) else { break };
                match run_one(job, opts) {
                    Ok(r) => {
                        eprintln!(
                            "[{}/{}] {} {} -> {} ({:?}, {:.1} s)",
                            i + 1,
                            jobs.len(),
                            r.dir,
                            r.label,
                            if r.reported.is_empty() { "-".to_string() } else { r.reported.join("+") },
                            r.outcome,
                            r.seconds
                        );
                        if let Ok(mut v) = results.lock() {
                            v.push((i, r));
                        }
                    }
                    Err(e) => {
                        if let Ok(mut v) = errors.lock() {
                            v.push(format!("{}: {e:#}", job.dir.display()));
                        }
                    }
                }
            });
        }
    });
    let errs = errors.into_inner().unwrap_or_default();
    if let Some(e) = errs.first() {
        anyhow::bail!("scorer failed: {e}");
    }
    let mut v = results.into_inner().unwrap_or_default();
    v.sort_by_key(|(i, _)| *i);
    Ok(v.into_iter().map(|(_, r)| r).collect())
}

/// One row of a grouped table.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Row {
    pub cases: usize,
    pub correct: usize,
    pub unsure: usize,
    pub refused: usize,
    pub over_claim: usize,
    /// What the tool said instead, when not correct.
    pub called_instead: BTreeMap<String, usize>,
}

impl Row {
    fn add(&mut self, r: &CaseResult) {
        self.cases += 1;
        match r.outcome {
            Outcome::Correct => self.correct += 1,
            Outcome::Unsure => self.unsure += 1,
            Outcome::Refused => self.refused += 1,
            Outcome::OverClaim => self.over_claim += 1,
            Outcome::Wrong => {}
        }
        if r.outcome != Outcome::Correct {
            let said = if r.outcome == Outcome::Refused { "(refused)".to_string() } else { r.reported.join("+") };
            *self.called_instead.entry(said).or_default() += 1;
        }
    }

    fn pct(&self) -> f64 {
        if self.cases == 0 {
            0.0
        } else {
            100.0 * self.correct as f64 / self.cases as f64
        }
    }
}

pub fn group(results: &[CaseResult], key: impl Fn(&CaseResult) -> String) -> BTreeMap<String, Row> {
    let mut m: BTreeMap<String, Row> = BTreeMap::new();
    for r in results {
        m.entry(key(r)).or_default().add(r);
    }
    m
}

fn print_table(title: &str, rows: &BTreeMap<String, Row>, confusion: bool) {
    println!("\n== {title} ==");
    println!(
        "{:<44} {:>5} {:>7} {:>6} {:>6} {:>7}  {}",
        "group",
        "cases",
        "correct",
        "%",
        "unsure",
        "refused",
        if confusion { "called instead" } else { "" }
    );
    for (k, r) in rows {
        let conf = if confusion {
            r.called_instead.iter().map(|(k, n)| format!("{k}×{n}")).collect::<Vec<_>>().join(", ")
        } else {
            String::new()
        };
        println!(
            "{:<44} {:>5} {:>7} {:>5.0}% {:>6} {:>7}  {}",
            k,
            r.cases,
            r.correct,
            r.pct(),
            r.unsure,
            r.refused,
            conf
        );
    }
}

/// Summary numbers of a set of results.
pub fn summary(results: &[CaseResult]) -> Value {
    let none: Vec<&CaseResult> = results.iter().filter(|r| r.label == "none").collect();
    let over = none.iter().filter(|r| r.outcome == Outcome::OverClaim).count();
    let correct = results.iter().filter(|r| r.outcome == Outcome::Correct).count();
    let refused = results.iter().filter(|r| r.outcome == Outcome::Refused).count();
    let unsure = results.iter().filter(|r| r.outcome == Outcome::Unsure).count();
    let effect_cases = results.iter().filter(|r| r.label != "none").count();
    let effect_correct = results.iter().filter(|r| r.label != "none" && r.outcome == Outcome::Correct).count();
    let strict_correct = results.iter().filter(|r| r.strict_correct).count();
    let with_optional = results.iter().filter(|r| !r.optional.is_empty()).count();
    json!({
        "strict_correct": strict_correct, "cases_with_optional_effects": with_optional,
        "cases": results.len(), "correct": correct, "unsure": unsure, "refused": refused,
        "none_cases": none.len(), "none_over_claims": over,
        "none_over_claim_rate": if none.is_empty() { 0.0 } else { over as f64 / none.len() as f64 },
        "effect_cases": effect_cases, "effect_correct": effect_correct,
        "seconds_total": results.iter().map(|r| r.seconds).sum::<f64>(),
    })
}

fn print_report(results: &[CaseResult]) {
    let classes: BTreeSet<&str> = results.iter().map(|r| r.seed_class.as_str()).collect();
    for class in &classes {
        let sub: Vec<CaseResult> = results.iter().filter(|r| r.seed_class == *class).cloned().collect();
        println!("\n######## seeds: {class} ({} cases) ########", sub.len());
        print_table("per family (truth)", &group(&sub, |r| r.label.clone()), true);
        print_table("per mode", &group(&sub, |r| r.mode.clone()), false);
        print_table("per trajectory family", &group(&sub, |r| r.trajectory_family.clone()), false);
        print_table("per rate band", &group(&sub, |r| r.rate_band.clone()), false);
        let s = summary(&sub);
        println!(
            "\nover-claim on none: {}/{} ({:.0}%)   correct overall: {}/{}   unsure: {}   refused: {}",
            at(&s, "none_over_claims"),
            at(&s, "none_cases"),
            100.0 * at(&s, "none_over_claim_rate").as_f64().unwrap_or(0.0),
            at(&s, "correct"),
            at(&s, "cases"),
            at(&s, "unsure"),
            at(&s, "refused")
        );
        println!(
            "strict (every drawn effect named, also those under SNR {SHOWN_SNR} in a compound, {} such cases): {}/{}",
            at(&s, "cases_with_optional_effects"),
            at(&s, "strict_correct"),
            at(&s, "cases")
        );
        for r in sub.iter().filter(|r| r.outcome == Outcome::Refused) {
            println!("  refused: {} exit {:?}: {}", r.dir, r.exit_code, r.stderr_tail.lines().last().unwrap_or(""));
        }
    }
}

/// The `run` command.
pub fn run(opts: &RunOpts) -> anyhow::Result<()> {
    let mut jobs = Vec::new();
    for d in &opts.cases_dirs {
        jobs.extend(load_jobs(d)?);
    }
    let results = run_all(&jobs, opts)?;
    print_report(&results);
    if let Some(out) = &opts.json_out {
        let classes: BTreeSet<String> = results.iter().map(|r| r.seed_class.clone()).collect();
        let mut by_class = serde_json::Map::new();
        for c in classes {
            let sub: Vec<CaseResult> = results.iter().filter(|r| r.seed_class == c).cloned().collect();
            by_class.insert(
                c,
                json!({
                    "summary": summary(&sub),
                    "per_family": group(&sub, |r| r.label.clone()),
                    "per_mode": group(&sub, |r| r.mode.clone()),
                    "per_trajectory_family": group(&sub, |r| r.trajectory_family.clone()),
                    "per_rate_band": group(&sub, |r| r.rate_band.clone()),
                }),
            );
        }
        let doc = json!({"summary": summary(&results), "by_seed_class": by_class, "cases": results});
        std::fs::write(out, serde_json::to_string_pretty(&doc)?)?;
    }
    Ok(())
}
