//! Planning: a sweep file expanded into rows (a full grid or a seeded Latin hypercube), each
//! row's scene written with its parameters applied and its file references made absolute.
//!
//! Keys are dotted paths into the base scene's TOML: `solver.tolerance`,
//! `mesh.file`, `region.material.youngs_modulus`. Where a path crosses an array of tables
//! (`region`, `boundary`), the value is set in every entry that has the rest of the path;
//! a 0-based index selects one entry (`boundary.1.displacement.z`). A key must exist in the
//! base scene (add it there, with any value, to sweep it). Text values of file keys
//! (`mesh.file`, `contact.skull`, `displacement_file`) are relative to the sweep file.

use std::path::{Path, PathBuf};

use bs_mesh::rng::SplitMix64;
use serde::Deserialize;
use toml::{Table, Value};

use super::{AxisValue, Manifest, Row, SweepError, create_dir, csv_field, write_text};
use bs_scene::Scene;

/// More rows than this is a mistake in the sweep file, not a plan.
const MAX_ROWS: usize = 1_000_000;

/// The sweep file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    base: PathBuf,
    #[serde(default)]
    method: Method,
    seed: Option<u64>,
    samples: Option<usize>,
    #[serde(rename = "axis", default)]
    axes: Vec<AxisSpec>,
}

#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum Method {
    #[default]
    Grid,
    Lhs,
}

/// One `[[axis]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxisSpec {
    key: String,
    values: Option<Vec<Value>>,
    range: Option<[f64; 2]>,
    samples: Option<usize>,
}

/// An axis resolved: its key and either its values (grid, or LHS over given values) or a
/// range (LHS).
#[derive(Debug)]
enum Axis {
    Values(Vec<AxisValue>),
    Range(f64, f64),
}

/// Plans the sweep file at `sweep` into `out`: `manifest.csv`, `manifest.json` and
/// `scenes/I.toml`. Planning the same sweep into the same folder again is a no-op; a
/// different sweep there is refused.
pub fn plan(sweep: &Path, out: &Path) -> Result<Manifest, SweepError> {
    let text = std::fs::read_to_string(sweep).map_err(|e| SweepError::File {
        file: sweep.to_path_buf(),
        message: format!("cannot read: {e}"),
    })?;
    plan_text(sweep, &text, out)
}

/// [`plan()`] for sweep text already read (`sweep` names it and anchors relative paths).
pub fn plan_text(sweep: &Path, text: &str, out: &Path) -> Result<Manifest, SweepError> {
    let file = std::path::absolute(sweep).unwrap_or_else(|_| sweep.to_path_buf());
    let err = |message: String| SweepError::File { file: file.clone(), message };
    let spec: SweepFile =
        toml::from_str(text).map_err(|e| err(e.to_string().trim_end().to_string()))?;
    let sweep_dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
    let base = sweep_dir.join(&spec.base);
    let base_text = std::fs::read_to_string(&base)
        .map_err(|e| err(format!("base = \"{}\": cannot read: {e}", spec.base.display())))?;
    // The base must be a valid scene on its own: its mistakes are reported against it.
    Scene::parse(&base_text).map_err(|m| SweepError::File { file: base.clone(), message: m })?;
    let mut base_table: Table = toml::from_str(&base_text)
        .map_err(|e| SweepError::File { file: base.clone(), message: e.to_string() })?;
    absolutise(&mut base_table, base.parent().unwrap_or(Path::new("")))
        .map_err(|m| SweepError::File { file: base.clone(), message: m })?;

    if spec.axes.is_empty() {
        return Err(err("no [[axis]]: give at least one, e.g. [[axis]] key = \
                        \"region.material.youngs_modulus\" values = [1500.0, 3000.0]"
            .into()));
    }
    let keys: Vec<String> = spec.axes.iter().map(|a| a.key.clone()).collect();
    for (i, k) in keys.iter().enumerate() {
        if keys[..i].contains(k) {
            return Err(err(format!("[[axis]] key = \"{k}\" appears twice; sweep it once")));
        }
    }
    let axes: Vec<Axis> = spec
        .axes
        .iter()
        .enumerate()
        .map(|(i, a)| resolve_axis(i, a, spec.method, &sweep_dir))
        .collect::<Result<_, String>>()
        .map_err(&err)?;
    // Every key must name something in the base scene, with a value of the axis's type.
    for (k, a) in keys.iter().zip(&axes) {
        let probe = match a {
            Axis::Values(v) => v[0].clone(),
            Axis::Range(lo, _) => AxisValue::Number(*lo),
        };
        set_key(&mut base_table.clone(), k, &probe).map_err(&err)?;
    }

    let parameters = match spec.method {
        Method::Grid => {
            if spec.seed.is_some() || spec.samples.is_some() {
                return Err(err("seed and samples (at the top level) belong to method = \
                                \"lhs\"; a grid takes samples per [[axis]]"
                    .into()));
            }
            grid(&axes).map_err(&err)?
        }
        Method::Lhs => {
            let n = spec.samples.filter(|&n| n >= 1).ok_or_else(|| {
                err("method = \"lhs\" needs samples = N (N >= 1, the number of rows) at the \
                     top level"
                    .into())
            })?;
            if n > MAX_ROWS {
                return Err(err(format!("samples = {n} exceeds {MAX_ROWS} rows")));
            }
            let seed = spec.seed.ok_or_else(|| {
                err("method = \"lhs\" needs seed = S (any integer; the same seed gives the \
                     same rows)"
                    .into())
            })?;
            lhs(&axes, n, seed).map_err(&err)?
        }
    };

    let manifest = Manifest {
        sweep: file.clone(),
        base: std::path::absolute(&base).unwrap_or(base.clone()),
        method: match spec.method {
            Method::Grid => "grid".into(),
            Method::Lhs => "lhs".into(),
        },
        seed: spec.seed,
        keys: keys.clone(),
        rows: parameters
            .into_iter()
            .enumerate()
            .map(|(index, parameters)| Row {
                index,
                parameters,
                scene: PathBuf::from("scenes").join(format!("{index}.toml")),
            })
            .collect(),
    };
    let json = serde_json::to_string_pretty(&manifest).expect("a manifest serialises");
    let json_path = out.join("manifest.json");
    if let Ok(existing) = std::fs::read_to_string(&json_path)
        && existing.trim_end() != json
    {
        return Err(SweepError::Dir {
            dir: out.to_path_buf(),
            message: "a different sweep is already planned in this folder; plan into \
                      another --out folder or delete this one"
                .into(),
        });
    }

    // Every row's scene is built and checked before anything is written.
    let mut scenes = Vec::with_capacity(manifest.rows.len());
    for row in &manifest.rows {
        let mut table = base_table.clone();
        for (k, v) in keys.iter().zip(&row.parameters) {
            set_key(&mut table, k, v).map_err(&err)?;
        }
        let body = toml::to_string(&table).map_err(|e| err(e.to_string()))?;
        Scene::parse(&body).map_err(|m| {
            err(format!("row {} ({}) is not a valid scene: {m}", row.index, describe(&keys, row)))
        })?;
        scenes.push(format!(
            "# brainshift sweep row {} of {}\n# base: {}\n# {}\n{body}",
            row.index,
            file.display(),
            manifest.base.display(),
            describe(&keys, row)
        ));
    }
    create_dir(&out.join("scenes"))?;
    for (row, body) in manifest.rows.iter().zip(&scenes) {
        write_text(&out.join(&row.scene), body)?;
    }
    let mut csv = String::from("index");
    for k in &keys {
        csv.push(',');
        csv.push_str(&csv_field(k));
    }
    csv.push_str(",scene\n");
    for row in &manifest.rows {
        csv.push_str(&row.index.to_string());
        for v in &row.parameters {
            csv.push(',');
            csv.push_str(&v.csv());
        }
        csv.push(',');
        csv.push_str(&csv_field(&row.scene.to_string_lossy()));
        csv.push('\n');
    }
    write_text(&out.join("manifest.csv"), &csv)?;
    write_text(&json_path, &format!("{json}\n"))?;
    Ok(manifest)
}

fn describe(keys: &[String], row: &Row) -> String {
    keys.iter()
        .zip(&row.parameters)
        .map(|(k, v)| match v {
            AxisValue::Number(x) => format!("{k} = {x:?}"),
            AxisValue::Text(s) => format!("{k} = \"{s}\""),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// File keys: their text values are paths.
fn is_file_key(key: &str) -> bool {
    let last = key.rsplit('.').next().unwrap_or(key);
    key == "mesh.file" || key == "contact.skull" || last == "displacement_file"
}

fn resolve_axis(i: usize, a: &AxisSpec, method: Method, sweep_dir: &Path) -> Result<Axis, String> {
    let at = format!("[[axis]] #{} (key = \"{}\")", i + 1, a.key);
    match (&a.values, a.range, a.samples) {
        (Some(values), None, None) => {
            if values.is_empty() {
                return Err(format!("{at}: values is empty; give at least one value"));
            }
            let mut out = Vec::with_capacity(values.len());
            for v in values {
                out.push(match v {
                    Value::Float(x) if x.is_finite() => AxisValue::Number(*x),
                    Value::Integer(n) => AxisValue::Number(*n as f64),
                    Value::String(s) if is_file_key(&a.key) => {
                        AxisValue::Text(path_text(&sweep_dir.join(s))?)
                    }
                    Value::String(s) => AxisValue::Text(s.clone()),
                    other => {
                        return Err(format!(
                            "{at}: values must be finite numbers or strings, found {other}"
                        ));
                    }
                });
            }
            let numbers = out.iter().filter(|v| matches!(v, AxisValue::Number(_))).count();
            if numbers != 0 && numbers != out.len() {
                return Err(format!("{at}: values mix numbers and strings; use one type"));
            }
            Ok(Axis::Values(out))
        }
        (None, Some([lo, hi]), samples) => {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(format!(
                    "{at}: range = [{lo}, {hi}] must be two finite numbers, low first"
                ));
            }
            match (method, samples) {
                (Method::Grid, Some(n)) if n >= 1 => {
                    let v = (0..n)
                        .map(|k| match (k, n) {
                            (_, 1) | (0, _) => lo,
                            _ if k == n - 1 => hi,
                            _ => lo + (hi - lo) * k as f64 / (n - 1) as f64,
                        })
                        .map(AxisValue::Number)
                        .collect();
                    Ok(Axis::Values(v))
                }
                (Method::Grid, _) => {
                    Err(format!("{at}: range needs samples = N (N >= 1) with method = \"grid\""))
                }
                (Method::Lhs, None) => Ok(Axis::Range(lo, hi)),
                (Method::Lhs, Some(_)) => Err(format!(
                    "{at}: with method = \"lhs\" give samples once at the top level (the \
                     number of rows), not per axis"
                )),
            }
        }
        _ => Err(format!(
            "{at}: give either values = [...] or range = [lo, hi] (with samples = N for a grid)"
        )),
    }
}

fn path_text(p: &Path) -> Result<String, String> {
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    abs.to_str()
        .map(str::to_string)
        .ok_or_else(|| format!("the path {} is not valid UTF-8", abs.display()))
}

/// Every combination, the first axis varying slowest.
fn grid(axes: &[Axis]) -> Result<Vec<Vec<AxisValue>>, String> {
    let lists: Vec<&Vec<AxisValue>> = axes
        .iter()
        .map(|a| match a {
            Axis::Values(v) => v,
            Axis::Range(..) => unreachable!("a grid axis always has values"),
        })
        .collect();
    let total = lists
        .iter()
        .try_fold(1usize, |acc, l| acc.checked_mul(l.len()))
        .filter(|&n| n <= MAX_ROWS)
        .ok_or(format!("the grid has more than {MAX_ROWS} rows; sweep fewer values"))?;
    let mut rows = Vec::with_capacity(total);
    for r in 0..total {
        let mut rest = r;
        let mut row = vec![AxisValue::Number(0.0); lists.len()];
        for (a, l) in lists.iter().enumerate().rev() {
            row[a] = l[rest % l.len()].clone();
            rest /= l.len();
        }
        rows.push(row);
    }
    Ok(rows)
}

/// A Latin hypercube of `n` rows: each axis's range is cut into `n` equal strata and every
/// stratum gets exactly one row (a uniform point in it), strata shuffled independently per
/// axis; an axis of `values` uses each value once (it must have `n` of them).
fn lhs(axes: &[Axis], n: usize, seed: u64) -> Result<Vec<Vec<AxisValue>>, String> {
    let mut rng = SplitMix64::new(seed);
    let mut columns = Vec::with_capacity(axes.len());
    for a in axes {
        let mut order: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = rng.below(i + 1);
            order.swap(i, j);
        }
        let column: Vec<AxisValue> = match a {
            Axis::Range(lo, hi) => order
                .iter()
                .map(|&s| {
                    let u = rng.uniform();
                    AxisValue::Number((lo + (hi - lo) * (s as f64 + u) / n as f64).min(*hi))
                })
                .collect(),
            Axis::Values(v) if v.len() == n => order.iter().map(|&s| v[s].clone()).collect(),
            Axis::Values(v) => {
                return Err(format!(
                    "an axis with values under method = \"lhs\" needs exactly samples = {n} \
                     values (each used once), found {}; or give range = [lo, hi]",
                    v.len()
                ));
            }
        };
        columns.push(column);
    }
    Ok((0..n).map(|r| columns.iter().map(|c| c[r].clone()).collect()).collect())
}

/// Makes the base scene's file references absolute (they were relative to its folder).
fn absolutise(t: &mut Table, dir: &Path) -> Result<(), String> {
    let fix = |v: &mut Value| -> Result<(), String> {
        if let Value::String(s) = v {
            *s = path_text(&dir.join(&*s))?;
        }
        Ok(())
    };
    if let Some(Value::Table(m)) = t.get_mut("mesh")
        && let Some(f) = m.get_mut("file")
    {
        fix(f)?;
    }
    if let Some(Value::Table(c)) = t.get_mut("contact")
        && let Some(f) = c.get_mut("skull")
    {
        fix(f)?;
    }
    if let Some(Value::Array(bs)) = t.get_mut("boundary") {
        for b in bs {
            if let Some(f) = b.as_table_mut().and_then(|b| b.get_mut("displacement_file")) {
                fix(f)?;
            }
        }
    }
    Ok(())
}

/// Sets `key` to `value` wherever it exists; an error names the key and lists the valid ones.
pub(crate) fn set_key(t: &mut Table, key: &str, value: &AxisValue) -> Result<usize, String> {
    let segments: Vec<&str> = key.split('.').collect();
    if segments.iter().any(|s| s.is_empty()) {
        return Err(format!("[[axis]] key = \"{key}\" is not a dotted path (a.b.c)"));
    }
    let mut root = Value::Table(std::mem::take(t));
    let result = set_in(&mut root, &segments, value, key);
    if let Value::Table(back) = root {
        *t = back;
    }
    match result? {
        0 => {
            let mut valid = Vec::new();
            leaves(&Value::Table(t.clone()), "", &mut valid);
            valid.dedup();
            Err(format!(
                "[[axis]] key = \"{key}\" names nothing in the base scene; valid keys: {} \
                 (an array of tables takes an optional 0-based index, e.g. \
                 boundary.1.displacement.z; add a key to the base scene to sweep it)",
                valid.join(", ")
            ))
        }
        n => Ok(n),
    }
}

fn set_in(v: &mut Value, segs: &[&str], new: &AxisValue, key: &str) -> Result<usize, String> {
    let Some((first, rest)) = segs.split_first() else { return Ok(0) };
    match v {
        Value::Table(t) => match t.get_mut(*first) {
            None => Ok(0),
            Some(child) if rest.is_empty() => {
                let replaced = match (&*child, new) {
                    (Value::Integer(_), AxisValue::Number(x))
                        if x.fract() == 0.0 && x.abs() < 9.0e15 =>
                    {
                        Value::Integer(*x as i64)
                    }
                    (Value::Integer(_), AxisValue::Number(x)) => {
                        return Err(format!(
                            "[[axis]] key = \"{key}\" holds a whole number in the base scene, \
                             but the axis gives {x}; give whole numbers"
                        ));
                    }
                    (Value::Float(_), AxisValue::Number(x)) => Value::Float(*x),
                    (Value::String(_), AxisValue::Text(s)) => Value::String(s.clone()),
                    (Value::Table(_) | Value::Array(_), _) => return Ok(0),
                    (old, _) => {
                        return Err(format!(
                            "[[axis]] key = \"{key}\" holds {} in the base scene, but the \
                             axis gives {}",
                            kind(old),
                            match new {
                                AxisValue::Number(_) => "numbers",
                                AxisValue::Text(_) => "text",
                            }
                        ));
                    }
                };
                *child = replaced;
                Ok(1)
            }
            Some(child) => set_in(child, rest, new, key),
        },
        Value::Array(items) => match first.parse::<usize>() {
            Ok(i) => match items.get_mut(i) {
                Some(item) => set_in(item, rest, new, key),
                None => Err(format!(
                    "[[axis]] key = \"{key}\": index {i} is out of range (the array has {} \
                     entries, 0-based)",
                    items.len()
                )),
            },
            Err(_) => {
                let mut n = 0;
                for item in items {
                    n += set_in(item, segs, new, key)?;
                }
                Ok(n)
            }
        },
        _ => Ok(0),
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "text",
        Value::Integer(_) | Value::Float(_) => "a number",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

/// Dotted paths of the scalar leaves (arrays of tables without an index).
fn leaves(v: &Value, prefix: &str, out: &mut Vec<String>) {
    match v {
        Value::Table(t) => {
            for (k, child) in t {
                let p = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                leaves(child, &p, out);
            }
        }
        Value::Array(items) if items.iter().all(Value::is_table) && !items.is_empty() => {
            for item in items {
                leaves(item, prefix, out);
            }
        }
        Value::Array(_) => {}
        _ => {
            if !out.contains(&prefix.to_string()) {
                out.push(prefix.to_string());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(rel: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures").join(rel)
    }

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("bs-sweep-plan-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A sweep file next to the cube fixtures (written into a temp folder whose base path
    /// points back at the fixture).
    fn sweep_file(dir: &Path, body: &str) -> PathBuf {
        let base = fixture("cube/uniaxial-t4.toml");
        let path = dir.join("sweep.toml");
        std::fs::write(&path, format!("base = {:?}\n{body}", base.to_str().unwrap())).unwrap();
        path
    }

    #[test]
    fn a_grid_has_the_product_of_the_axis_counts_first_axis_slowest() {
        let d = temp("grid");
        let s = sweep_file(
            &d,
            "[[axis]]\nkey = \"region.material.youngs_modulus\"\nvalues = [1000.0, 2000.0, 3000.0]\n\
             [[axis]]\nkey = \"region.material.poisson_ratio\"\nrange = [0.3, 0.45]\nsamples = 4\n",
        );
        let m = plan(&s, &d.join("out")).unwrap();
        assert_eq!(m.rows.len(), 12);
        assert_eq!(m.rows[0].parameters, [AxisValue::Number(1000.0), AxisValue::Number(0.3)]);
        assert_eq!(m.rows[3].parameters, [AxisValue::Number(1000.0), AxisValue::Number(0.45)]);
        assert_eq!(m.rows[4].parameters[0], AxisValue::Number(2000.0));
        // Each row's scene parses, carries its values and points at the real mesh.
        let row = Scene::load(&d.join("out/scenes/5.toml")).unwrap();
        assert_eq!(row.regions[0].material.youngs_modulus, Some(2000.0));
        assert_eq!(row.regions[0].material.poisson_ratio, Some(0.35));
        assert!(row.mesh.file.is_absolute() && row.mesh.file.exists(), "{:?}", row.mesh.file);
        let csv = std::fs::read_to_string(d.join("out/manifest.csv")).unwrap();
        assert!(csv.starts_with(
            "index,region.material.youngs_modulus,region.material.poisson_ratio,scene\n0,1000.0,0.3,scenes/0.toml\n"
        ), "{csv}");
        assert_eq!(csv.lines().count(), 13);
        // Planning again is a no-op; a different sweep in the same folder is refused.
        assert_eq!(plan(&s, &d.join("out")).unwrap(), m);
        let s2 = sweep_file(
            &d,
            "[[axis]]\nkey = \"region.material.youngs_modulus\"\nvalues = [1000.0]\n",
        );
        let e = plan(&s2, &d.join("out")).unwrap_err().to_string();
        assert!(e.contains("a different sweep is already planned"), "{e}");
    }

    #[test]
    fn an_indexed_key_sets_one_entry_and_an_unindexed_key_every_entry() {
        let d = temp("indexed");
        let s = sweep_file(
            &d,
            "[[axis]]\nkey = \"boundary.3.displacement.z\"\nvalues = [-0.05]\n\
             [[axis]]\nkey = \"solver.tolerance\"\nvalues = [1e-8]\n",
        );
        let m = plan(&s, &d.join("out")).unwrap();
        assert_eq!(m.rows.len(), 1);
        let row = Scene::load(&d.join("out/scenes/0.toml")).unwrap();
        assert_eq!(row.boundaries[3].displacement.unwrap().z, Some(-0.05));
        assert_eq!(row.solver.tolerance, 1e-8);
    }

    #[test]
    fn latin_hypercube_puts_one_sample_in_every_stratum_of_every_axis() {
        let d = temp("lhs");
        let n = 10;
        let s = sweep_file(
            &d,
            &format!(
                "method = \"lhs\"\nseed = 7\nsamples = {n}\n\
                 [[axis]]\nkey = \"region.material.youngs_modulus\"\nrange = [1500.0, 6000.0]\n\
                 [[axis]]\nkey = \"region.material.poisson_ratio\"\nrange = [0.45, 0.49]\n"
            ),
        );
        let m = plan(&s, &d.join("out")).unwrap();
        assert_eq!(m.rows.len(), n);
        for (a, (lo, hi)) in [(1500.0, 6000.0), (0.45, 0.49)].into_iter().enumerate() {
            let mut strata: Vec<usize> = m
                .rows
                .iter()
                .map(|r| match r.parameters[a] {
                    AxisValue::Number(x) => {
                        assert!((lo..=hi).contains(&x), "{x}");
                        (((x - lo) / (hi - lo) * n as f64) as usize).min(n - 1)
                    }
                    AxisValue::Text(_) => panic!("number expected"),
                })
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..n).collect::<Vec<_>>(), "axis {a}");
        }
        // Seeded: the same seed gives the same rows, another seed other rows.
        let again = lhs(&[Axis::Range(0.0, 1.0)], n, 7).unwrap();
        assert_eq!(again, lhs(&[Axis::Range(0.0, 1.0)], n, 7).unwrap());
        assert_ne!(again, lhs(&[Axis::Range(0.0, 1.0)], n, 8).unwrap());
    }

    #[test]
    fn mistakes_in_the_sweep_file_name_the_key_and_the_fix() {
        let d = temp("errors");
        let cases = [
            (
                "[[axis]]\nkey = \"region.material.youngs_modulu\"\nvalues = [1.0]\n",
                "key = \"region.material.youngs_modulu\" names nothing in the base scene; valid keys: ",
            ),
            ("[[axis]]\nkey = \"boundary.9.fix\"\nvalues = [1.0]\n", "index 9 is out of range"),
            ("[[axis]]\nkey = \"units\"\nvalues = [1.0]\n", "holds text in the base scene"),
            (
                "[[axis]]\nkey = \"region.material.youngs_modulus\"\nrange = [1.0, 2.0]\n",
                "range needs samples",
            ),
            (
                "[[axis]]\nkey = \"region.material.youngs_modulus\"\nvalues = []\n",
                "values is empty",
            ),
            (
                "method = \"lhs\"\nseed = 1\n[[axis]]\nkey = \"solver.tolerance\"\nrange = [1.0, 2.0]\n",
                "needs samples = N",
            ),
            (
                "[[axis]]\nkey = \"region.material.poisson_ratio\"\nvalues = [0.3, 0.5]\n",
                "row 1 (region.material.poisson_ratio = 0.5) is not a valid scene: ",
            ),
            ("", "no [[axis]]"),
            ("[[axes]]\nkey = \"a\"\n", "unknown field `axes`"),
        ];
        for (i, (body, expect)) in cases.into_iter().enumerate() {
            let s = sweep_file(&d, body);
            let e = plan(&s, &d.join(format!("out{i}"))).unwrap_err().to_string();
            assert!(e.contains(expect), "{body}: {e}");
            assert!(e.contains("sweep.toml"), "{e}");
        }
        let e = plan(&s_missing(&d), &d.join("o")).unwrap_err().to_string();
        assert!(e.contains("cannot read"), "{e}");
        // The unknown-key message lists what can be swept.
        let s = sweep_file(&d, "[[axis]]\nkey = \"nope\"\nvalues = [1.0]\n");
        let e = plan(&s, &d.join("o2")).unwrap_err().to_string();
        for k in ["region.material.youngs_modulus", "mesh.file", "boundary.displacement.z"] {
            assert!(e.contains(k), "{e}");
        }
    }

    fn s_missing(d: &Path) -> PathBuf {
        d.join("no-such-sweep.toml")
    }

    #[test]
    fn a_mesh_file_axis_is_a_path_relative_to_the_sweep_file() {
        let d = temp("meshfile");
        let s = sweep_file(&d, "[[axis]]\nkey = \"mesh.file\"\nvalues = [\"cube.msh\"]\n");
        plan(&s, &d.join("out")).unwrap();
        let row = Scene::load(&d.join("out/scenes/0.toml")).unwrap();
        assert_eq!(row.mesh.file, std::path::absolute(d.join("cube.msh")).unwrap());
    }
}
