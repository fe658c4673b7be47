//! `brainshift gap`: the brain–skull gap of every boundary node (or of given points), the
//! diagnostic users run before a simulation.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use bs_contact::{Handler, MasterSurface, PaperParams};
use bs_mesh::Point3;

use bs_scene::scene::Algorithm;

/// What to measure.
#[derive(Debug)]
pub enum Query {
    /// Boundary nodes of a volume mesh (ids: the file's node ids).
    Mesh(PathBuf),
    /// Points from a CSV with a header naming columns x, y, z (ids: 0-based rows).
    Points(PathBuf),
}

/// Reads `x,y,z` columns (found by header name) from a CSV.
fn read_points(path: &Path) -> Result<Vec<Point3<f64>>, String> {
    let f = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{f}: {e}"))?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or(format!("{f}: empty file; expected a header x,y,z"))?;
    let names: Vec<String> = header.split(',').map(|h| h.trim().to_ascii_lowercase()).collect();
    let col = |c: &str| {
        names.iter().position(|n| n == c).ok_or(format!(
            "{f}:1: the header has no column '{c}' (found: {header}); name the columns x,y,z"
        ))
    };
    let (cx, cy, cz) = (col("x")?, col("y")?, col("z")?);
    let mut points = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let get = |c: usize| -> Result<f64, String> {
            let v = fields.get(c).ok_or(format!(
                "{f}:{}: expected {} columns, found {}",
                i + 1,
                names.len(),
                fields.len()
            ))?;
            v.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or(format!("{f}:{}: '{v}' is not a finite number", i + 1))
        };
        points.push(Point3::new(get(cx)?, get(cy)?, get(cz)?));
    }
    Ok(points)
}

/// Runs `gap`; exits 1 when any node is outside the skull.
pub fn run(
    skull_path: &Path,
    query: &Query,
    algorithm: Algorithm,
    out: Option<&Path>,
) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let skull = bs_mesh::io::read_surface(skull_path)?;
    let sk = skull_path.display();
    let master = std::sync::Arc::new(MasterSurface::new(&skull).map_err(|e| format!("{sk}: {e}"))?);
    let mut handler = Handler::from_master(algorithm, master.clone(), PaperParams::default())
        .map_err(|e| format!("{sk}: {e}"))?;
    let (ids, points): (Vec<u64>, Vec<Point3<f64>>) = match query {
        Query::Mesh(path) => {
            let mesh = bs_mesh::io::read_mesh(path)?;
            if let Some(e) = mesh.validate().first_error() {
                return Err(format!("{}: {e}", path.display()).into());
            }
            let b = mesh.boundary();
            b.volume_node.iter().map(|&n| (mesh.node_ids[n], mesh.nodes[n])).unzip()
        }
        Query::Points(path) => {
            let p = read_points(path)?;
            ((0..p.len() as u64).collect(), p)
        }
    };
    let rows = bs_contact::gap(&mut handler, &master, &points);

    let mut csv = String::from("id,signed_distance,closest_x,closest_y,closest_z,outside\n");
    for (id, r) in ids.iter().zip(&rows) {
        csv.push_str(&format!(
            "{id},{:?},{:?},{:?},{:?},{}\n",
            r.signed_distance,
            r.closest.x,
            r.closest.y,
            r.closest.z,
            u8::from(r.outside)
        ));
    }
    match out {
        Some(path) => bs_mesh::io::write_atomic(path, |w| w.write_all(csv.as_bytes()))?,
        None => crate::emit(&csv),
    }
    let outside: Vec<(u64, f64)> = ids
        .iter()
        .zip(&rows)
        .filter(|(_, r)| r.outside)
        .map(|(&i, r)| (i, r.signed_distance))
        .collect();
    let min = rows.iter().map(|r| r.signed_distance).fold(f64::INFINITY, f64::min);
    let max = rows.iter().map(|r| r.signed_distance).fold(f64::NEG_INFINITY, f64::max);
    eprintln!(
        "{} points: gap min {min:.6}, max {max:.6} (positive = inside the skull); {} outside{}",
        rows.len(),
        outside.len(),
        if outside.is_empty() {
            String::new()
        } else {
            let list: Vec<String> =
                outside.iter().take(10).map(|(i, d)| format!("{i} ({d:.4})")).collect();
            format!(": {}{}", list.join(", "), if outside.len() > 10 { ", ..." } else { "" })
        }
    );
    Ok(if outside.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}
