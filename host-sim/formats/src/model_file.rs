//! The joint model TOML (spec §2) and its conversion to and from the core's parameters.
//!
//! Which keys exist is not written down here: every scalar key is a [`ParamDesc`] of the core's
//! [`PARAMS`] table (`section`, `key`), so a parameter added to the core is a TOML key at once.
//! The file is parsed with serde; its sections are the table's sections too (an unknown one is
//! refused with the list of known ones), unknown keys inside a section are refused by the lookup
//! in `PARAMS`; both errors name the key and its line.
//! Every section is optional; a key left out takes the table default (0 for every model term,
//! so a missing section is a term the model does not have).
//!
//! The gravity table's `axes` are log columns: `"q"` is the joint's own angle (axis source 0),
//! every other name (`"q_<joint>"`) gets the next free slot 1..=3 in order of first appearance;
//! [`ModelFile::other_columns`] returns that mapping so a log's `q_<name>` columns can feed the
//! core's `Input::others`.
//!
//! `[presliding]` (spec §2, `sigma` N·m/rad) is a section of the model and of a plant alike: with
//! `sigma > 0` the Coulomb terms `friction.c·sign(q̇)` and `dry_friction.c·sign(q̇)` become one
//! Dahl friction state of level `friction.c + dry_friction.c` (see `joint_core::model::
//! Presliding`), so the model's prediction on a log depends on the samples before
//! ([`crate::predict::predicted`] runs it in order). A file without the section, or with
//! `sigma = 0`, has no such state.
//!
//! Optional extension (not in spec §2, which it does not change): `[gravity_series]`, the
//! analytic multi-angle gravity term of the core ([`joint_core::series`]),
//! `τ_s = Σ amplitude[k]·sin(Σ_i mult[k][i]·angle_i + phase[k])`:
//! ```toml
//! [gravity_series]
//! angles = ["q", "q_j2", "q_j3"]   # the angles the multipliers refer to (log columns, like table axes)
//! amplitude = [2.38, -0.59]        # N·m
//! phase = [0.0, 1.5707963]         # rad
//! mult = [[1, 0, 0], [1, -1, 1]]   # one integer vector per term, |m| ≤ 4
//! table_residual = true            # optional: the gravity table holds this model's residual
//! ```
//! Angles other than `q` share the slots 1..=3 with the table's axes (series angles first). Keys
//! are checked strictly: an unknown key is an error naming it, a bad term names its index.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use joint_core::params::{
    self, ParamDesc, ParamError, ParamId, ParamSet, RawParams, RawSeries, RawTable, PARAMS, PARAM_COUNT,
};
use joint_core::table::{AXES_MAX, AXIS_POINTS_MAX, CELLS_MAX};
use serde::Deserialize;
use toml::Spanned;

/// A section of scalar keys, validated against `PARAMS` after parsing.
pub type Section = BTreeMap<String, Spanned<f64>>;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravityTableToml {
    pub axes: Spanned<Vec<String>>,
    pub grid: Spanned<Vec<Vec<f64>>>,
    pub torque: Spanned<Vec<f64>>,
    #[serde(default)]
    pub sigma: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    pub sigma_model: Option<Spanned<f64>>,
    #[serde(default)]
    pub clamp_k: Option<Spanned<f64>>,
}

/// `[gravity_series]` as written in the file (see the module documentation).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GravitySeriesToml {
    pub angles: Spanned<Vec<String>>,
    pub amplitude: Spanned<Vec<f64>>,
    pub phase: Spanned<Vec<f64>>,
    pub mult: Spanned<Vec<Vec<i64>>>,
    #[serde(default)]
    pub table_residual: Option<Spanned<bool>>,
}

/// The model file as written: every section of the core's parameter table (by its name there,
/// so a term added to the table is a section here at once), the gravity table and series, and
/// the name. Sections that `owned` claims (a plant file's effects and sensors) are skipped for
/// their owner to read; anything else is refused, naming the sections a file may have.
pub(crate) struct ModelToml {
    pub name: Option<String>,
    pub sections: Vec<(&'static str, Section)>,
    pub gravity_table: Option<GravityTableToml>,
    pub gravity_series: Option<GravitySeriesToml>,
}

struct ModelSeed<'a> {
    owned: &'a dyn Fn(&str) -> bool,
}

impl<'de> serde::de::DeserializeSeed<'de> for ModelSeed<'_> {
    type Value = ModelToml;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<ModelToml, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> serde::de::Visitor<'de> for ModelSeed<'_> {
    type Value = ModelToml;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a model file (sections of scalar keys)")
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<ModelToml, A::Error> {
        use serde::de::Error as _;
        let mut m = ModelToml { name: None, sections: Vec::new(), gravity_table: None, gravity_series: None };
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "name" => m.name = Some(map.next_value()?),
                "gravity_table" => m.gravity_table = Some(map.next_value()?),
                "gravity_series" => m.gravity_series = Some(map.next_value()?),
                k if (self.owned)(k) => {
                    map.next_value::<serde::de::IgnoredAny>()?;
                }
                k => match params::sections().find(|s| *s == k) {
                    Some(section) => m.sections.push((section, map.next_value::<Section>()?)),
                    None => {
                        let known: Vec<&str> = params::sections().collect();
                        return Err(A::Error::custom(format!(
                            "unknown section `{k}` (a model file has: name, {}, gravity_table, gravity_series)",
                            known.join(", ")
                        )));
                    }
                },
            }
        }
        Ok(m)
    }
}

impl ModelToml {
    fn parse(text: &str, owned: &dyn Fn(&str) -> bool) -> Result<ModelToml, toml::de::Error> {
        use serde::de::DeserializeSeed as _;
        ModelSeed { owned }.deserialize(toml::Deserializer::parse(text)?)
    }
}

/// The gravity series as the file gives it (names, f64), before it becomes a core `RawSeries`.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesSpec {
    /// the angles the multipliers refer to: `q` or `q_<name>` log columns
    pub angles: Vec<String>,
    pub amplitude: Vec<f64>,
    pub phase: Vec<f64>,
    pub mult: Vec<Vec<i64>>,
    /// the gravity table is the residual of the model (weight + series)
    pub table_residual: bool,
}

/// The gravity table as the file gives it (f64, names), before it becomes a core `RawTable`.
#[derive(Clone, Debug, PartialEq)]
pub struct TableSpec {
    pub axes: Vec<String>,
    pub grid: Vec<Vec<f64>>,
    pub torque: Vec<f64>,
    pub sigma: Option<Vec<f64>>,
}

/// A parsed model file: the values the file sets explicitly (by `ParamId` index), the line each
/// came from, and the gravity table.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelFile {
    pub name: Option<String>,
    values: [Option<f64>; PARAM_COUNT],
    lines: [Option<usize>; PARAM_COUNT],
    pub table: Option<TableSpec>,
    table_line: Option<usize>,
    /// the optional `[gravity_series]` extension
    pub series: Option<SeriesSpec>,
    series_line: Option<usize>,
    /// file name for error messages
    pub file: String,
}

/// Why a model file was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("{file}: cannot read: {msg}")]
    Io { file: String, msg: String },
    #[error("{file}: {msg}")]
    Toml { file: String, msg: String },
    #[error("{file}: line {line}: unknown key `{key}` in [{section}] (known keys: {known})")]
    UnknownKey { file: String, line: usize, section: String, key: String, known: String },
    #[error("{file}: line {line}: [gravity_table] {key}: {msg}")]
    Table { file: String, line: usize, key: &'static str, msg: String },
    #[error("{file}: {location}[{section}] {key}: {msg}")]
    Param { file: String, location: String, section: &'static str, key: &'static str, msg: String },
    #[error("{file}: line {line}: [gravity_series] {msg}")]
    Series { file: String, line: usize, msg: String },
}

fn line_of(text: &str, offset: usize) -> usize {
    1 + text.as_bytes().iter().take(offset).filter(|&&b| b == b'\n').count()
}

fn known_keys(section: &str) -> String {
    params::section_params(section).map(|d| d.key).collect::<Vec<_>>().join(", ")
}

impl ModelFile {
    /// An empty model: every parameter at its default, no table.
    pub fn empty(file: &str) -> ModelFile {
        ModelFile {
            name: None,
            values: [None; PARAM_COUNT],
            lines: [None; PARAM_COUNT],
            table: None,
            table_line: None,
            series: None,
            series_line: None,
            file: file.to_string(),
        }
    }

    pub fn read_file(path: &Path) -> Result<ModelFile, ModelError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|e| ModelError::Io { file: file.clone(), msg: e.to_string() })?;
        Self::parse(&text, &file)
    }

    /// Parses model TOML text; `file` is only used in messages.
    pub fn parse(text: &str, file: &str) -> Result<ModelFile, ModelError> {
        Self::parse_except(text, file, &|_| false)
    }

    /// Parses the model part of a file that has sections of its own (a plant file's effects):
    /// those `owned` claims are left to the caller, every other one is the model's or an error.
    pub fn parse_except(text: &str, file: &str, owned: &dyn Fn(&str) -> bool) -> Result<ModelFile, ModelError> {
        let toml = ModelToml::parse(text, owned)
            .map_err(|e| ModelError::Toml { file: file.to_string(), msg: e.to_string() })?;
        Self::from_toml(&toml, text, file)
    }

    pub(crate) fn from_toml(toml: &ModelToml, text: &str, file: &str) -> Result<ModelFile, ModelError> {
        let sections: Vec<(&'static str, Option<&Section>)> =
            toml.sections.iter().map(|(s, v)| (*s, Some(v))).collect();
        let mut mf = Self::from_parts(toml.name.clone(), &sections, toml.gravity_table.as_ref(), text, file)?;
        if let Some(g) = &toml.gravity_series {
            mf.series_line = Some(line_of(text, g.angles.span().start));
            mf.series = Some(SeriesSpec {
                angles: g.angles.get_ref().clone(),
                amplitude: g.amplitude.get_ref().clone(),
                phase: g.phase.get_ref().clone(),
                mult: g.mult.get_ref().clone(),
                table_residual: g.table_residual.as_ref().is_some_and(|r| *r.get_ref()),
            });
            // Shape and term errors now, with the file's line, not only when the set is built.
            mf.raw_params()?;
        }
        Ok(mf)
    }

    pub fn from_parts(
        name: Option<String>,
        sections: &[(&'static str, Option<&Section>)],
        table: Option<&GravityTableToml>,
        text: &str,
        file: &str,
    ) -> Result<ModelFile, ModelError> {
        let mut mf = ModelFile::empty(file);
        mf.name = name;
        for (section, keys) in sections {
            let Some(keys) = keys else { continue };
            for (key, value) in keys.iter() {
                let line = line_of(text, value.span().start);
                let Some(d) = params::param_at(section, key) else {
                    return Err(ModelError::UnknownKey {
                        file: file.to_string(),
                        line,
                        section: section.to_string(),
                        key: key.clone(),
                        known: known_keys(section),
                    });
                };
                mf.set(d.id, *value.get_ref(), Some(line));
            }
        }
        if let Some(t) = table {
            for (id, v) in [(ParamId::TableSigmaModel, &t.sigma_model), (ParamId::TableClampK, &t.clamp_k)] {
                if let Some(v) = v {
                    mf.set(id, *v.get_ref(), Some(line_of(text, v.span().start)));
                }
            }
            mf.table_line = Some(line_of(text, t.axes.span().start));
            mf.table = Some(TableSpec {
                axes: t.axes.get_ref().clone(),
                grid: t.grid.get_ref().clone(),
                torque: t.torque.get_ref().clone(),
                sigma: t.sigma.as_ref().map(|s| s.get_ref().clone()),
            });
        }
        Ok(mf)
    }

    /// Sets a parameter explicitly (`line` = where it came from, if from a file).
    pub fn set(&mut self, id: ParamId, value: f64, line: Option<usize>) {
        if let Some(v) = self.values.get_mut(id.index()) {
            *v = Some(value);
        }
        if let Some(l) = self.lines.get_mut(id.index()) {
            *l = line;
        }
    }

    /// The value the file sets for `id`, if it sets one.
    pub fn explicit(&self, id: ParamId) -> Option<f64> {
        self.values.get(id.index()).copied().flatten()
    }

    /// The value for `id`: the file's, else the core's default.
    pub fn value(&self, id: ParamId) -> f64 {
        self.explicit(id).unwrap_or_else(|| f64::from(id.desc().default))
    }

    /// The value at a TOML place (`"friction"`, `"c"`), file value or default; `None` if no
    /// parameter lives there.
    pub fn get(&self, section: &str, key: &str) -> Option<f64> {
        params::param_at(section, key).map(|d| self.value(d.id))
    }

    /// Log columns feeding the core's `others[0..3]`, in slot order of first appearance: the
    /// series' angles first (a written-back file lists all four slots there, in order, so its
    /// slots survive a round trip), then the table's axes.
    pub fn other_columns(&self) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        let table = self.table.iter().flat_map(|t| t.axes.iter());
        let series = self.series.iter().flat_map(|s| s.angles.iter());
        for a in series.chain(table) {
            if a != "q" && !v.contains(a) {
                v.push(a.clone());
            }
        }
        v
    }

    fn location(&self, id: ParamId) -> String {
        match self.lines.get(id.index()).copied().flatten() {
            Some(l) => format!("line {l}: "),
            None => String::new(),
        }
    }

    fn param_error(&self, e: ParamError) -> ModelError {
        match e.param() {
            Some(id) => {
                let d = id.desc();
                let what = if self.explicit(id).is_some() { "" } else { " (default; not set in the file)" };
                ModelError::Param {
                    file: self.file.clone(),
                    location: self.location(id),
                    section: d.section,
                    key: d.key,
                    msg: format!("{e}{what}"),
                }
            }
            None if matches!(e, ParamError::Series(_)) => self.series_error(e.to_string()),
            None => ModelError::Table {
                file: self.file.clone(),
                line: self.table_line.unwrap_or(0),
                key: "grid/torque/sigma",
                msg: e.to_string(),
            },
        }
    }

    fn series_error(&self, msg: String) -> ModelError {
        ModelError::Series { file: self.file.clone(), line: self.series_line.unwrap_or(0), msg }
    }

    /// The series as the core's `RawSeries` (slots as [`ModelFile::other_columns`] assigns
    /// them). Terms are checked here with their index; the core checks them again at `check`.
    fn raw_series(&self, s: &SeriesSpec) -> Result<RawSeries, ModelError> {
        use joint_core::series::{AMPLITUDE_MAX, MULT_MAX, PHASE_MAX, TERMS_MAX};
        let n = s.amplitude.len();
        if n > TERMS_MAX {
            return Err(self.series_error(format!("{n} terms, at most {TERMS_MAX} fit")));
        }
        if s.phase.len() != n || s.mult.len() != n {
            return Err(self.series_error(format!(
                "amplitude, phase and mult need one entry per term: {n}, {}, {} given",
                s.phase.len(),
                s.mult.len()
            )));
        }
        if s.angles.is_empty() || s.angles.len() > 4 {
            return Err(self.series_error(format!("angles: {} given, 1..=4 supported", s.angles.len())));
        }
        let others = self.other_columns();
        if others.len() > 3 {
            return Err(self.series_error(format!(
                "{} other joints named by the table and the series, at most 3 fit",
                others.len()
            )));
        }
        let mut slot_of = Vec::new();
        for (i, a) in s.angles.iter().enumerate() {
            if s.angles.iter().take(i).any(|b| b == a) {
                return Err(self.series_error(format!("angles: `{a}` appears twice")));
            }
            if a != "q" && !(a.len() > 2 && a.starts_with("q_")) {
                return Err(self.series_error(format!("angles: `{a}` is not a log angle column (`q` or `q_<name>`)")));
            }
            slot_of.push(if a == "q" { 0 } else { 1 + others.iter().position(|o| o == a).unwrap_or(0) });
        }
        let mut rs = RawSeries::EMPTY;
        for k in 0..n {
            let a = s.amplitude.get(k).copied().unwrap_or(f64::NAN);
            let p = s.phase.get(k).copied().unwrap_or(f64::NAN);
            let m = s.mult.get(k).cloned().unwrap_or_default();
            if !(a.is_finite() && a.abs() <= f64::from(AMPLITUDE_MAX)) {
                return Err(
                    self.series_error(format!("term {k}: amplitude = {a}: must be finite, |a| ≤ {AMPLITUDE_MAX} N·m"))
                );
            }
            if !(p.is_finite() && p.abs() <= f64::from(PHASE_MAX)) {
                return Err(self.series_error(format!("term {k}: phase = {p}: must be finite, |φ| ≤ {PHASE_MAX} rad")));
            }
            if m.len() != s.angles.len() {
                return Err(self.series_error(format!(
                    "term {k}: mult has {} entries, one per angle ({}) needed",
                    m.len(),
                    s.angles.len()
                )));
            }
            let mut v = [0i8; 4];
            for (i, &x) in m.iter().enumerate() {
                if x.abs() > i64::from(MULT_MAX) {
                    return Err(self.series_error(format!("term {k}: mult[{i}] = {x}: |m| ≤ {MULT_MAX}")));
                }
                if let Some(d) = slot_of.get(i).and_then(|&sl| v.get_mut(sl)) {
                    *d = x as i8;
                }
            }
            if let (Some(da), Some(dp), Some(dm)) = (rs.amplitude.get_mut(k), rs.phase.get_mut(k), rs.mult.get_mut(k)) {
                *da = a as f32;
                *dp = p as f32;
                *dm = v;
            }
        }
        rs.n_terms = n as u8;
        Ok(rs)
    }

    fn table_error(&self, key: &'static str, msg: String) -> ModelError {
        ModelError::Table { file: self.file.clone(), line: self.table_line.unwrap_or(0), key, msg }
    }

    /// The core's raw parameters (unchecked by the core, but the table shape is checked here).
    pub fn raw_params(&self) -> Result<RawParams, ModelError> {
        let mut raw = RawParams::defaults();
        for d in PARAMS.iter() {
            if let Some(v) = self.explicit(d.id) {
                // f64 → f32 rounds to nearest; values outside f32 become ±inf and check() names them.
                raw.set(d.id, v as f32);
            }
        }
        if let Some(t) = &self.table {
            raw.table = self.raw_table(t)?;
        }
        if let Some(s) = &self.series {
            raw.series = self.raw_series(s)?;
            if s.table_residual {
                if raw.table.n_axes == 0 {
                    return Err(self.series_error("table_residual = true needs a [gravity_table]".into()));
                }
                raw.table.residual = true;
            }
        }
        Ok(raw)
    }

    fn raw_table(&self, t: &TableSpec) -> Result<RawTable, ModelError> {
        let mut rt = RawTable::EMPTY;
        let n = t.axes.len();
        if n == 0 || n > AXES_MAX {
            return Err(self.table_error("axes", format!("{n} axes given, 1..={AXES_MAX} supported")));
        }
        let others = self.other_columns();
        if others.len() > 3 {
            return Err(self.table_error("axes", format!("{} other joints named, at most 3 fit", others.len())));
        }
        for (i, a) in t.axes.iter().enumerate() {
            if t.axes.iter().take(i).any(|b| b == a) {
                return Err(self.table_error("axes", format!("axis `{a}` appears twice")));
            }
            if a != "q" && !(a.len() > 2 && a.starts_with("q_")) {
                return Err(
                    self.table_error("axes", format!("axis `{a}` is not a log angle column (`q` or `q_<name>`)"))
                );
            }
            let src = if a == "q" { 0 } else { 1 + others.iter().position(|o| o == a).unwrap_or(0) };
            if let Some(s) = rt.axis_source.get_mut(i) {
                *s = src as u8;
            }
        }
        if t.grid.len() != n {
            return Err(self.table_error("grid", format!("{} grid rows for {n} axes", t.grid.len())));
        }
        let mut cells = 1usize;
        for (i, g) in t.grid.iter().enumerate() {
            if g.len() < 2 || g.len() > AXIS_POINTS_MAX {
                return Err(self.table_error(
                    "grid",
                    format!("grid[{i}] has {} points, 2..={AXIS_POINTS_MAX} supported", g.len()),
                ));
            }
            cells *= g.len();
            if let (Some(p), Some(row)) = (rt.points.get_mut(i), rt.grid.get_mut(i)) {
                *p = g.len() as u8;
                for (dst, src) in row.iter_mut().zip(g) {
                    *dst = *src as f32;
                }
            }
        }
        if cells > CELLS_MAX {
            return Err(self.table_error("grid", format!("{cells} cells, at most {CELLS_MAX} fit")));
        }
        if t.torque.len() != cells {
            return Err(
                self.table_error("torque", format!("{} values, the grid needs {cells} (row-major)", t.torque.len()))
            );
        }
        for (dst, src) in rt.torque.iter_mut().zip(&t.torque) {
            *dst = *src as f32;
        }
        if let Some(s) = &t.sigma {
            if s.len() != cells {
                return Err(self.table_error("sigma", format!("{} values, the grid needs {cells}", s.len())));
            }
            for (dst, src) in rt.sigma.iter_mut().zip(s) {
                *dst = *src as f32;
            }
            rt.has_sigma = true;
        }
        rt.n_axes = n as u8;
        Ok(rt)
    }

    /// The validated parameter set; errors name the TOML key (and its line when set in the file).
    pub fn param_set(&self) -> Result<ParamSet, ModelError> {
        let raw = self.raw_params()?;
        params::check(&raw).map_err(|e| self.param_error(e))
    }

    /// A model file holding `raw`: sections whose values all equal the defaults are left out
    /// (for the model terms that means "all zero"); `other_columns` names slots 1..=3 of the
    /// gravity table's axis sources (missing names become `q_other<slot>`).
    pub fn from_raw(raw: &RawParams, name: Option<&str>, other_columns: &[String]) -> ModelFile {
        let mut mf = ModelFile::empty("(generated)");
        mf.name = name.map(str::to_string);
        let sections = section_order();
        for s in sections {
            let descs: Vec<&ParamDesc> = params::section_params(s).collect();
            let differs = descs.iter().any(|d| raw.get(d.id).to_bits() != d.default.to_bits());
            let has_table = s == "gravity_table" && raw.table.n_axes > 0;
            if differs || has_table {
                for d in descs {
                    mf.set(d.id, f32_to_f64_shortest(raw.get(d.id)), None);
                }
            }
        }
        let t = &raw.table;
        if t.n_axes > 0 {
            let n = (t.n_axes as usize).min(AXES_MAX);
            let cells = t.cells().min(CELLS_MAX);
            let axes = t
                .axis_source
                .iter()
                .take(n)
                .map(|&s| match s {
                    0 => "q".to_string(),
                    s => other_columns.get(s as usize - 1).cloned().unwrap_or_else(|| format!("q_other{s}")),
                })
                .collect();
            let grid = (0..n)
                .map(|a| {
                    let p = t.points.get(a).copied().unwrap_or(0) as usize;
                    t.grid
                        .get(a)
                        .map(|g| g.iter().take(p).map(|&x| f32_to_f64_shortest(x)).collect())
                        .unwrap_or_default()
                })
                .collect();
            let torque = t.torque.iter().take(cells).map(|&x| f32_to_f64_shortest(x)).collect();
            let sigma = t.has_sigma.then(|| t.sigma.iter().take(cells).map(|&x| f32_to_f64_shortest(x)).collect());
            mf.table = Some(TableSpec { axes, grid, torque, sigma });
        }
        let s = &raw.series;
        if s.n_terms > 0 || t.residual {
            // All four angle slots, named as the table names them.
            let name = |slot: usize| match slot {
                0 => "q".to_string(),
                s => other_columns.get(s - 1).cloned().unwrap_or_else(|| format!("q_other{s}")),
            };
            let n = s.n_terms as usize;
            mf.series = Some(SeriesSpec {
                angles: (0..4).map(name).collect(),
                amplitude: s.amplitude.iter().take(n).map(|&x| f32_to_f64_shortest(x)).collect(),
                phase: s.phase.iter().take(n).map(|&x| f32_to_f64_shortest(x)).collect(),
                mult: s.mult.iter().take(n).map(|m| m.iter().map(|&x| i64::from(x)).collect()).collect(),
                table_residual: t.residual,
            });
        }
        mf
    }

    /// TOML text in the spec's layout, units as comments; reads back to the same values.
    pub fn to_toml_string(&self) -> String {
        let mut out = String::new();
        if let Some(n) = &self.name {
            let _ = writeln!(out, "name = {}", toml_string(n));
        }
        for s in section_order() {
            let descs: Vec<&ParamDesc> = params::section_params(s).filter(|d| self.explicit(d.id).is_some()).collect();
            let table = if s == "gravity_table" { self.table.as_ref() } else { None };
            if descs.is_empty() && table.is_none() {
                continue;
            }
            let _ = writeln!(out, "\n[{s}]");
            if let Some(t) = table {
                let axes: Vec<String> = t.axes.iter().map(|a| toml_string(a)).collect();
                let _ = writeln!(out, "axes = [{}]", axes.join(", "));
                let rows: Vec<String> = t.grid.iter().map(|g| format!("[{}]", num_list(g))).collect();
                let _ = writeln!(out, "grid = [{}]  # rad", rows.join(", "));
                let _ = writeln!(out, "torque = [{}]  # N·m, row-major", num_list(&t.torque));
                if let Some(sg) = &t.sigma {
                    let _ = writeln!(out, "sigma = [{}]  # N·m", num_list(sg));
                }
            }
            for d in descs {
                let v = self.explicit(d.id).unwrap_or(0.0);
                let _ = writeln!(out, "{} = {}  # {}", d.key, toml_num(v), d.unit);
            }
        }
        if let Some(s) = &self.series {
            let _ = writeln!(out, "\n[gravity_series]");
            let angles: Vec<String> = s.angles.iter().map(|a| toml_string(a)).collect();
            let _ = writeln!(out, "angles = [{}]", angles.join(", "));
            let _ = writeln!(out, "amplitude = [{}]  # N·m", num_list(&s.amplitude));
            let _ = writeln!(out, "phase = [{}]  # rad", num_list(&s.phase));
            let mult: Vec<String> = s
                .mult
                .iter()
                .map(|m| format!("[{}]", m.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(", ")))
                .collect();
            let _ = writeln!(out, "mult = [{}]", mult.join(", "));
            if s.table_residual {
                let _ = writeln!(out, "table_residual = true");
            }
        }
        out
    }
}

/// TOML sections in `PARAMS` order (gravity_table included).
fn section_order() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = params::sections().collect();
    if !v.contains(&"gravity_table") {
        v.push("gravity_table");
    }
    v
}

/// The f64 whose shortest decimal is the f32's shortest decimal, so `1.894f32` prints as
/// `1.894` and reads back to the same f32.
fn f32_to_f64_shortest(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}

fn toml_num(v: f64) -> String {
    if v.is_finite() {
        let s = format!("{v:?}");
        // `{:?}` always shows a decimal point or exponent, so TOML reads a float.
        s
    } else if v.is_nan() {
        "nan".into()
    } else if v > 0.0 {
        "inf".into()
    } else {
        "-inf".into()
    }
}

fn num_list(v: &[f64]) -> String {
    v.iter().map(|&x| toml_num(x)).collect::<Vec<_>>().join(", ")
}

fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}
