//! clap value parsers over the libraries' own enums: the analysis and format crates name their
//! choices (`NAMES` tables) without depending on clap, and the CLI turns a table into the same
//! `[possible values: …]` help and error that `clap::ValueEnum` would give.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

/// A parser for `(name, value)` pairs.
pub fn named<T: Copy + Send + Sync + 'static>(names: &'static [(&'static str, T)]) -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(names.iter().map(|(n, _)| PossibleValue::new(*n)))
        .try_map(move |s: String| lookup(names.iter().map(|(n, v)| (*n, *v)), &s))
}

/// A parser for `(name, value, help)` triples: the help is listed under `--help`.
pub fn described<T: Copy + Send + Sync + 'static>(
    names: &'static [(&'static str, T, &'static str)],
) -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(names.iter().map(|(n, _, h)| PossibleValue::new(*n).help(*h)))
        .try_map(move |s: String| lookup(names.iter().map(|(n, v, _)| (*n, *v)), &s))
}

/// PossibleValuesParser has already refused anything not in the table; this only maps the name.
fn lookup<T>(mut names: impl Iterator<Item = (&'static str, T)>, s: &str) -> Result<T, String> {
    names.find(|(n, _)| *n == s).map(|(_, v)| v).ok_or_else(|| format!("unknown value `{s}`"))
}
