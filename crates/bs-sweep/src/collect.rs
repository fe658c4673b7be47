//! Collecting a sweep: one table `DIR/summary.csv` with a row per planned row: its
//! parameters, status (`ok`, `failed`, `missing`), error, largest displacement, the
//! displacement at named reference points (interpolated in the mesh's tetrahedra), the
//! nodes in contact and the solve time.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, Point3, TetLocator, Vector3};

use super::run::{has_report, row_dir};
use super::{AxisValue, Manifest, SweepError, csv_field, write_text};
use bs_scene::Scene;

/// A named reference point (mesh length units).
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPoint {
    /// Its name (a column prefix in the summary).
    pub name: String,
    /// Its position in the reference configuration.
    pub point: Point3<f64>,
}

/// How a row ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Converged and verified; its files are in `runs/I/`.
    Ok,
    /// Failed; `runs/I/error.json` says why.
    Failed,
    /// Not run (yet).
    Missing,
}

impl Status {
    /// `"ok"`, `"failed"` or `"missing"`.
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Failed => "failed",
            Status::Missing => "missing",
        }
    }
}

/// One row of the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// The row.
    pub index: usize,
    /// Its parameters, one per key.
    pub parameters: Vec<AxisValue>,
    /// How it ended.
    pub status: Status,
    /// The error of a failed row (or why its results could not be read).
    pub error: Option<String>,
    /// Largest nodal displacement magnitude.
    pub max_displacement: Option<f64>,
    /// Displacement at each named point, in the order given.
    pub at_points: Vec<Option<Vector3<f64>>>,
    /// Slave nodes on the skull at the end.
    pub nodes_in_contact: Option<u64>,
    /// Wall time from known displacements to the verified result (seconds).
    pub solve_seconds: Option<f64>,
    /// Length unit of the lengths.
    pub units: Option<String>,
}

/// The collected table.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The swept keys.
    pub keys: Vec<String>,
    /// The named points.
    pub points: Vec<NamedPoint>,
    /// One row per planned row.
    pub rows: Vec<SummaryRow>,
    /// Where the table was written.
    pub path: PathBuf,
}

impl Summary {
    /// Rows with `status`.
    pub fn count(&self, status: Status) -> usize {
        self.rows.iter().filter(|r| r.status == status).count()
    }

    /// The header of summary.csv.
    pub fn header(&self) -> Vec<String> {
        let mut h = vec!["index".to_string()];
        h.extend(self.keys.iter().cloned());
        h.extend(["status", "error", "max_displacement"].map(String::from));
        for p in &self.points {
            for c in ["ux", "uy", "uz", "umag"] {
                h.push(format!("{}_{c}", p.name));
            }
        }
        h.extend(["nodes_in_contact", "solve_seconds", "units"].map(String::from));
        h
    }
}

/// Reads a points file: a header naming `name,x,y,z` (in any order), one point per line.
pub fn read_points(path: &Path) -> Result<Vec<NamedPoint>, SweepError> {
    let f = path.display();
    let bad = |message: String| SweepError::File { file: path.to_path_buf(), message };
    let text = std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or(bad("empty file; expected a header name,x,y,z".into()))?;
    let names: Vec<String> = header.split(',').map(|h| h.trim().to_ascii_lowercase()).collect();
    let col = |c: &str| {
        names.iter().position(|n| n == c).ok_or(bad(format!(
            "line 1: the header has no column '{c}' (found: {header}); name the columns name,x,y,z"
        )))
    };
    let (cn, cx, cy, cz) = (col("name")?, col("x")?, col("y")?, col("z")?);
    let mut points: Vec<NamedPoint> = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let field = |c: usize| {
            fields.get(c).copied().ok_or(bad(format!(
                "line {}: expected {} columns, found {}",
                i + 1,
                names.len(),
                fields.len()
            )))
        };
        let num = |c: usize| -> Result<f64, SweepError> {
            let v = field(c)?;
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or(bad(format!("line {}: '{v}' is not a finite number", i + 1)))
        };
        let name = field(cn)?.to_string();
        if name.is_empty() || name.contains(['"', ',']) {
            return Err(bad(format!("line {}: a point needs a plain name (no commas)", i + 1)));
        }
        if points.iter().any(|p| p.name == name) {
            return Err(bad(format!("line {}: the name '{name}' is used twice", i + 1)));
        }
        points.push(NamedPoint { name, point: Point3::new(num(cx)?, num(cy)?, num(cz)?) });
    }
    if points.is_empty() {
        return Err(bad(format!("{f} holds no point; give one per line after the header")));
    }
    Ok(points)
}

/// Collects every row of the sweep in `dir` into `DIR/summary.csv`.
pub fn collect(dir: &Path, points: &[NamedPoint]) -> Result<Summary, SweepError> {
    let manifest = Manifest::read(dir)?;
    // Meshes and their locators, read once per mesh file.
    let mut located: HashMap<PathBuf, Result<(Mesh, TetLocator), String>> = HashMap::new();
    let mut rows = Vec::with_capacity(manifest.rows.len());
    for row in &manifest.rows {
        let out = row_dir(dir, row.index);
        let mut r = SummaryRow {
            index: row.index,
            parameters: row.parameters.clone(),
            status: Status::Missing,
            error: None,
            max_displacement: None,
            at_points: vec![None; points.len()],
            nodes_in_contact: None,
            solve_seconds: None,
            units: None,
        };
        if has_report(&out) {
            r.status = Status::Ok;
            if let Ok(report) = bs_scene::output::RunReport::read(&out.join("report.json")) {
                r.max_displacement = Some(report.max_displacement);
                r.nodes_in_contact = Some(report.nodes_in_contact as u64);
                r.solve_seconds = Some(report.solve_seconds);
                r.units = report.units.map(|u| u.symbol().to_string());
            }
            if !points.is_empty() {
                match at_points(dir, &row.scene, &out, points, &mut located) {
                    Ok(values) => r.at_points = values.into_iter().map(Some).collect(),
                    Err(e) => r.error = Some(format!("displacement at the points: {e}")),
                }
            }
        } else if let Ok(text) = std::fs::read_to_string(out.join("error.json")) {
            r.status = Status::Failed;
            let json: serde_json::Value = serde_json::from_str(&text).unwrap_or_default();
            r.error = Some(
                json["message"]
                    .as_str()
                    .map_or_else(|| format!("unreadable error.json: {text}"), str::to_string),
            );
        }
        rows.push(r);
    }
    let summary = Summary {
        keys: manifest.keys.clone(),
        points: points.to_vec(),
        rows,
        path: dir.join("summary.csv"),
    };
    write_text(&summary.path, &to_csv(&summary))?;
    Ok(summary)
}

fn to_csv(s: &Summary) -> String {
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x:?}"));
    let mut csv = s.header().iter().map(|h| csv_field(h)).collect::<Vec<_>>().join(",");
    csv.push('\n');
    for r in &s.rows {
        let mut f = vec![r.index.to_string()];
        f.extend(r.parameters.iter().map(AxisValue::csv));
        f.push(r.status.name().into());
        f.push(csv_field(r.error.as_deref().unwrap_or("")));
        f.push(opt(r.max_displacement));
        for u in &r.at_points {
            match u {
                Some(u) => f.extend([u.x, u.y, u.z, u.norm()].map(|x| format!("{x:?}"))),
                None => f.extend(std::iter::repeat_n(String::new(), 4)),
            }
        }
        f.push(r.nodes_in_contact.map_or(String::new(), |n| n.to_string()));
        f.push(opt(r.solve_seconds));
        f.push(r.units.clone().unwrap_or_default());
        csv.push_str(&f.join(","));
        csv.push('\n');
    }
    csv
}

/// The displacement of a finished row at each point: its displacements.csv interpolated in
/// the tetrahedra of its mesh.
fn at_points(
    dir: &Path,
    scene: &Path,
    out: &Path,
    points: &[NamedPoint],
    located: &mut HashMap<PathBuf, Result<(Mesh, TetLocator), String>>,
) -> Result<Vec<Vector3<f64>>, String> {
    let scene = Scene::load(&dir.join(scene)).map_err(|e| e.to_string())?;
    let entry = located.entry(scene.mesh.file.clone()).or_insert_with(|| {
        let mesh = bs_mesh::io::read_mesh(&scene.mesh.file).map_err(|e| e.to_string())?;
        let locator =
            TetLocator::new(&mesh).map_err(|e| format!("{}: {e}", scene.mesh.file.display()))?;
        Ok((mesh, locator))
    });
    let (mesh, locator) = entry.as_ref().map_err(Clone::clone)?;
    let csv_path = out.join("displacements.csv");
    let text = std::fs::read_to_string(&csv_path)
        .map_err(|e| format!("{}: cannot read: {e}", csv_path.display()))?;
    let index: HashMap<u64, usize> =
        mesh.node_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let mut u = vec![Vector3::zeros(); mesh.nodes.len()];
    for (i, line) in text.lines().enumerate().skip(1) {
        let bad = || format!("{}:{}: expected node_id,ux,uy,uz", csv_path.display(), i + 1);
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 4 {
            return Err(bad());
        }
        let id: u64 = f[0].parse().map_err(|_| bad())?;
        let n = *index.get(&id).ok_or_else(bad)?;
        let c = |k: usize| f[k].parse::<f64>().map_err(|_| bad());
        u[n] = Vector3::new(c(1)?, c(2)?, c(3)?);
    }
    Ok(points.iter().map(|p| locator.interpolate(&u, &p.point)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run_row;

    #[test]
    fn collect_reports_ok_failed_and_missing_rows_with_point_values() {
        let dir = crate::planned_cube_sweep(
            "collect",
            "[[axis]]\nkey = \"boundary.3.displacement.z\"\nvalues = [-0.1, -0.9, -0.05]\n",
        );
        let d = dir.parent().unwrap().to_path_buf();
        run_row(&dir, 0, 1, &mut |_| {}).unwrap();
        assert!(run_row(&dir, 1, 1, &mut |_| {}).is_err());
        std::fs::write(d.join("points.csv"), "name,x,y,z\ntop,0.5,0.5,1.0\nbottom,0.5,0.5,0.0\n")
            .unwrap();
        let points = read_points(&d.join("points.csv")).unwrap();
        let s = collect(&dir, &points).unwrap();
        assert_eq!(s.rows.len(), 3);
        assert_eq!(
            (s.count(Status::Ok), s.count(Status::Failed), s.count(Status::Missing)),
            (1, 1, 1)
        );
        let ok = &s.rows[0];
        approx::assert_relative_eq!(ok.max_displacement.unwrap(), 0.1, max_relative = 0.5);
        // The top face moves down by 0.1; the bottom face centre stays (z fixed).
        let top = ok.at_points[0].unwrap();
        approx::assert_abs_diff_eq!(top.z, -0.1, epsilon = 1e-6);
        approx::assert_abs_diff_eq!(ok.at_points[1].unwrap().z, 0.0, epsilon = 1e-9);
        assert!(s.rows[1].error.as_ref().unwrap().contains("exceeds half the mesh size"));
        let csv = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
        let header = csv.lines().next().unwrap();
        assert_eq!(
            header,
            "index,boundary.3.displacement.z,status,error,max_displacement,top_ux,top_uy,top_uz,\
             top_umag,bottom_ux,bottom_uy,bottom_uz,bottom_umag,nodes_in_contact,solve_seconds,units"
        );
        assert!(csv.lines().nth(2).unwrap().starts_with("1,-0.9,failed,"), "{csv}");
        assert!(csv.lines().nth(3).unwrap().starts_with("2,-0.05,missing,,"), "{csv}");
    }

    #[test]
    fn a_bad_points_file_names_the_line() {
        let d = std::env::temp_dir().join(format!("bs-sweep-points-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("p.csv");
        for (body, expect) in [
            ("name,x,y\n", "no column 'z'"),
            ("name,x,y,z\na,1,2,zz\n", "line 2: 'zz' is not a finite number"),
            ("name,x,y,z\na,1,2\n", "line 2: expected 4 columns"),
            ("name,x,y,z\na,1,2,3\na,1,2,3\n", "used twice"),
            ("", "empty file"),
        ] {
            std::fs::write(&p, body).unwrap();
            let e = read_points(&p).unwrap_err().to_string();
            assert!(e.contains(expect) && e.contains("p.csv"), "{body}: {e}");
        }
    }
}
