//! No std float method anywhere in `firmware/`: on the PC, `x.sin()` resolves to std and would
//! compute other bits than the chip. The core must go through `joint_core::math`.

use std::fs;
use std::path::Path;

const BANNED: &[&str] = &[
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "atan2",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "sin_cos",
    "sqrt",
    "cbrt",
    "exp",
    "exp2",
    "exp_m1",
    "ln",
    "log",
    "log2",
    "log10",
    "ln_1p",
    "powi",
    "powf",
    "hypot",
    "mul_add",
    "floor",
    "ceil",
    "round",
    "trunc",
    "fract",
    "abs",
    "signum",
    "copysign",
    "rem_euclid",
    "div_euclid",
    "recip",
    "to_degrees",
    "to_radians",
];

/// `.name(` occurrences of banned methods in code (comments stripped), as (line, method).
fn offences(src: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in src.lines().enumerate() {
        let code = match line.find("//") {
            Some(i) => &line[..i],
            None => line,
        };
        let bytes = code.as_bytes();
        for (i, _) in code.match_indices('.') {
            let rest = &code[i + 1..];
            let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
            let after = rest[name.len()..].trim_start();
            // A method call: `.name(`; skip numeric literals like `1.5` (digit before the dot).
            let prev_is_digit =
                i > 0 && bytes[i - 1].is_ascii_digit() && name.chars().next().is_some_and(|c| c.is_ascii_digit());
            if !prev_is_digit && after.starts_with('(') && BANNED.contains(&name.as_str()) {
                found.push((n + 1, name));
            }
        }
    }
    found
}

fn scan(dir: &Path, out: &mut Vec<String>) {
    let Ok(entries) = fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n == "target") {
                continue;
            }
            scan(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") && p.components().any(|c| c.as_os_str() == "src") {
            let src = fs::read_to_string(&p).unwrap();
            for (line, m) in offences(&src) {
                out.push(format!("{}:{line}: .{m}()", p.display()));
            }
        }
    }
}

#[test]
fn scanner_finds_float_methods() {
    let sample =
        "let a = x.sin();\nlet b = libm::sinf(x); // x.sqrt() in a comment\nlet c = 1.5f32;\nlet d = v.abs ();";
    assert_eq!(offences(sample), vec![(1, "sin".to_string()), (4, "abs".to_string())]);
}

#[test]
fn no_std_float_methods_in_firmware_sources() {
    let root = joint_tests::workspace_root().join("firmware");
    let mut out = Vec::new();
    scan(&root, &mut out);
    assert!(out.is_empty(), "std float methods in firmware/ (use joint_core::math):\n{}", out.join("\n"));
}
