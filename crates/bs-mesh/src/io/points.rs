//! Point clouds: the vertices of whatever a scanner or a pipeline wrote, by extension.
//!
//! `.csv` (a header naming `x`, `y` and `z` columns, case-insensitive, other columns
//! ignored), `.ply` ([`super::ply`]), `.vtk` (legacy `POLYDATA` or `UNSTRUCTURED_GRID`
//! points), `.vtp` (VTK XML `PolyData` points), and the vertices of `.stl`, `.obj` and
//! `.off` surfaces. Repeated vertices (an STL's corners, shared by several facets) count
//! once. Non-finite coordinates are errors naming the point.

use std::collections::HashSet;
use std::path::Path;

use nalgebra::Point3;

use super::{Location, MeshIoError, ParseError};

/// The point-cloud formats, for help texts.
pub const EXTENSIONS: &str = ".csv, .ply, .vtk, .vtp, .stl, .obj, .off";

/// Reads the points of `path` (see the module documentation).
pub fn read_points(path: &Path) -> Result<Vec<Point3<f64>>, MeshIoError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let known = ["csv", "ply", "vtk", "vtp", "stl", "obj", "off"];
    if !ext.as_deref().is_some_and(|e| known.contains(&e)) {
        return Err(MeshIoError::Unsupported {
            file: path.to_path_buf(),
            message: format!("unknown point-cloud extension; use one of {EXTENSIONS}"),
        });
    }
    let bytes = super::read_bytes(path)?;
    let points = match ext.as_deref() {
        Some("csv") => read_csv(&bytes, path)?,
        Some("ply") => super::ply::read(&bytes, path)?,
        Some("vtk") => super::vtk::read_points(&bytes, path)?,
        Some("vtp") => super::vtu::read_polydata_points(&bytes, path)?,
        Some("stl") => super::stl::read(&bytes, path)?.vertices,
        Some("obj") => super::obj::read(&bytes, path)?.vertices,
        _ => super::off::read(&bytes, path)?.vertices,
    };
    if let Some(i) = points.iter().position(|p| !p.coords.iter().all(|x| x.is_finite())) {
        return Err(ParseError::new(
            path,
            Location::File,
            format!("point {i} is not finite ({:?}); every coordinate must be a number", points[i]),
        )
        .into());
    }
    Ok(unique(points))
}

/// The points with exact repeats removed, first occurrences in order.
fn unique(points: Vec<Point3<f64>>) -> Vec<Point3<f64>> {
    let mut seen = HashSet::with_capacity(points.len());
    points.into_iter().filter(|p| seen.insert(p.coords.map(|x| (x + 0.0).to_bits()))).collect()
}

/// Points from CSV text with a header naming the `x`, `y`, `z` columns.
pub fn read_csv(bytes: &[u8], file: &Path) -> Result<Vec<Point3<f64>>, ParseError> {
    let text = std::str::from_utf8(super::strip_bom(bytes))
        .map_err(|_| ParseError::new(file, Location::File, "not UTF-8 text"))?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (hl, header) = lines
        .next()
        .ok_or_else(|| ParseError::new(file, Location::File, "empty file: no header x,y,z"))?;
    let names: Vec<String> =
        header.split(',').map(|s| s.trim().trim_matches('"').to_ascii_lowercase()).collect();
    let column = |axis: &str| names.iter().position(|n| n == axis);
    let (Some(x), Some(y), Some(z)) = (column("x"), column("y"), column("z")) else {
        return Err(ParseError::new(
            file,
            Location::Line(hl + 1),
            format!("the header must name the columns x, y and z, found '{header}'"),
        ));
    };
    let mut points = Vec::new();
    for (l, line) in lines {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != names.len() {
            return Err(ParseError::new(
                file,
                Location::Line(l + 1),
                format!(
                    "expected {} columns as the header has, found {}",
                    names.len(),
                    fields.len()
                ),
            ));
        }
        let value = |c: usize| super::parse_field::<f64>(file, l + 1, fields[c], "a coordinate");
        points.push(Point3::new(value(x)?, value(y)?, value(z)?));
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_columns_by_name_in_any_order_and_errors_name_the_line() {
        let t = "id,Z,y,X\n1,3,2,1\n\n2,6,5,4\n";
        let p = read_csv(t.as_bytes(), Path::new("a.csv")).unwrap();
        assert_eq!(p, vec![Point3::new(1.0, 2.0, 3.0), Point3::new(4.0, 5.0, 6.0)]);
        let e = read_csv(b"x,y,z\n1,2,3\n1,2\n", Path::new("b.csv")).unwrap_err();
        assert_eq!(e.location, Location::Line(3));
        let e = read_csv(b"x,y,z\n1,2,oops\n", Path::new("b.csv")).unwrap_err();
        assert_eq!(e.location, Location::Line(2));
        assert!(read_csv(b"a,b,c\n1,2,3\n", Path::new("c.csv")).is_err());
        assert!(read_csv(b"", Path::new("d.csv")).is_err());
    }

    #[test]
    fn repeats_count_once() {
        let p = vec![
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 2.0, 3.0),
        ];
        assert_eq!(unique(p).len(), 2);
        // −0 and +0 are the same point.
        assert_eq!(unique(vec![Point3::new(-0.0, 0.0, 0.0), Point3::origin()]).len(), 1);
    }
}
