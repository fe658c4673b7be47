//! Landmark pairs as trackers and viewers write them, read into the scene's frame:
//!
//! * `.csv` with header `x,y,z,x2,y2,z2` (pre-operative, intra-operative; the scene's frame);
//! * MNI `.tag` files with `Volumes = 2;` (the public RESECT and BITE data), RAS;
//! * 3D Slicer markups, two files paired by label: `.fcsv` (its `# CoordinateSystem =`
//!   line: `RAS`/`0` or `LPS`/`1`) and `.mrk.json` (its `coordinateSystem`).
//!
//! Every landmark keeps where it came from (`line 7`, `label "F-3"`) for messages.

use std::path::Path;

use bs_mesh::Point3;

use bs_image::Space;

use crate::scene::LandmarkFiles;

/// Landmark pairs in the scene's frame, with where each was read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Pairs {
    pub pre: Vec<Point3<f64>>,
    pub intra: Vec<Point3<f64>>,
    /// Per landmark: `line N` of its file, or `label "…"`.
    pub origin: Vec<String>,
}

/// Points of one markup or tag file, with a label or line each, and their frame.
struct Labelled {
    points: Vec<(String, Point3<f64>)>,
    frame: Space,
}

/// Reads the landmark files into `space` (the scene's frame). Errors are messages that
/// name the file and line or label.
pub fn read_pairs(files: &LandmarkFiles, space: Space) -> Result<Pairs, String> {
    let pairs = match files {
        LandmarkFiles::Pairs(f) => match extension(f).as_str() {
            "csv" => read_csv(f, space)?,
            "tag" => read_tag(f, space)?,
            other => {
                return Err(format!(
                    "{}: unknown landmark file type '.{other}': give a .csv of pairs \
                     (x,y,z,x2,y2,z2), an MNI .tag file, or two 3D Slicer markups files \
                     [\"pre.mrk.json\", \"intra.mrk.json\"] paired by label",
                    f.display()
                ));
            }
        },
        LandmarkFiles::Split([a, b]) => {
            pair_by_label(a, &read_markups(a)?, b, &read_markups(b)?)?.into_frame(space)
        }
    };
    if pairs.pre.is_empty() {
        return Err(format!("{}: no landmark pairs", files.describe()));
    }
    Ok(pairs)
}

impl Pairs {
    /// The pairs read in RAS, in `space`.
    fn into_frame(mut self, space: Space) -> Pairs {
        if space == Space::Lps {
            for p in self.pre.iter_mut().chain(self.intra.iter_mut()) {
                *p = Space::Ras.convert_point(space, *p);
            }
        }
        self
    }
}

fn extension(f: &Path) -> String {
    let name = f.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if name.ends_with(".mrk.json") {
        return "mrk.json".into();
    }
    f.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
}

fn read_text(f: &Path) -> Result<String, String> {
    std::fs::read_to_string(f).map_err(|e| format!("{}: {e}", f.display()))
}

/// Finite numbers of `fields`, or an error naming the line.
fn numbers(f: &Path, line: usize, fields: &[&str]) -> Result<Vec<f64>, String> {
    fields
        .iter()
        .map(|s| match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => {
                Err(format!("{}: line {line}: '{}' is not a finite number", f.display(), s.trim()))
            }
        })
        .collect()
}

/// `.csv` pairs with header `x,y,z,x2,y2,z2` (the scene's frame).
fn read_csv(f: &Path, _space: Space) -> Result<Pairs, String> {
    let text = read_text(f)?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .map(|(_, h)| h.split(',').map(|s| s.trim().to_ascii_lowercase()).collect())
        .unwrap_or_default();
    if header != ["x", "y", "z", "x2", "y2", "z2"] {
        return Err(format!(
            "{}: line 1: the header must be x,y,z,x2,y2,z2 (pre-operative, then \
             intra-operative position)",
            f.display()
        ));
    }
    let mut pairs = Pairs::default();
    for (l, line) in lines {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != 6 {
            return Err(format!(
                "{}: line {}: expected 6 numbers, found {}",
                f.display(),
                l + 1,
                fields.len()
            ));
        }
        let v = numbers(f, l + 1, &fields)?;
        pairs.pre.push(Point3::new(v[0], v[1], v[2]));
        pairs.intra.push(Point3::new(v[3], v[4], v[5]));
        pairs.origin.push(format!("line {}", l + 1));
    }
    Ok(pairs)
}

/// An MNI `.tag` file with two volumes: after `Points =`, one tag per line (six
/// coordinates, then optional weight, structure, patient ids and a quoted label), the last
/// ending with `;`. RAS (world coordinates of MINC volumes).
fn read_tag(f: &Path, space: Space) -> Result<Pairs, String> {
    let text = read_text(f)?;
    if !text.trim_start().starts_with("MNI Tag Point File") {
        return Err(format!(
            "{}: line 1: not an MNI tag file (it must start with 'MNI Tag Point File')",
            f.display()
        ));
    }
    let mut pairs = Pairs::default();
    let mut in_points = false;
    let mut volumes = None;
    for (l, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if !in_points {
            let compact: String = line.chars().filter(|c| !c.is_whitespace()).collect();
            if let Some(v) = compact.strip_prefix("Volumes=") {
                volumes = v.trim_end_matches(';').parse::<u32>().ok();
            }
            if let Some(rest) = compact.strip_prefix("Points=") {
                in_points = true;
                if rest.is_empty() {
                    continue;
                }
            } else {
                continue;
            }
        }
        let body =
            line.strip_prefix("Points").map_or(line, |r| r.trim_start().trim_start_matches('='));
        let done = body.trim_end().ends_with(';');
        let body = body.trim_end().trim_end_matches(';');
        let fields: Vec<&str> = body.split_whitespace().collect();
        if !fields.is_empty() {
            if volumes != Some(2) {
                return Err(format!(
                    "{}: line {}: a landmark pair needs a tag file with 'Volumes = 2;' (found {})",
                    f.display(),
                    l + 1,
                    volumes.map_or("none".into(), |v| v.to_string())
                ));
            }
            if fields.len() < 6 {
                return Err(format!(
                    "{}: line {}: a tag needs six coordinates (x y z of both volumes), found {}",
                    f.display(),
                    l + 1,
                    fields.len()
                ));
            }
            let v = numbers(f, l + 1, &fields[..6])?;
            pairs.pre.push(Point3::new(v[0], v[1], v[2]));
            pairs.intra.push(Point3::new(v[3], v[4], v[5]));
            pairs.origin.push(format!("line {}", l + 1));
        }
        if done {
            break;
        }
    }
    if !in_points {
        return Err(format!("{}: no 'Points =' section", f.display()));
    }
    Ok(pairs.into_frame(space))
}

/// 3D Slicer markups: `.fcsv` or `.mrk.json`, each point with its label, in RAS.
fn read_markups(f: &Path) -> Result<Labelled, String> {
    let l = match extension(f).as_str() {
        "fcsv" => read_fcsv(f)?,
        "mrk.json" | "json" => read_mrk_json(f)?,
        other => {
            return Err(format!(
                "{}: unknown markups file type '.{other}': give 3D Slicer .fcsv or .mrk.json",
                f.display()
            ));
        }
    };
    let points = match l.frame {
        Space::Ras => l.points,
        Space::Lps => l
            .points
            .into_iter()
            .map(|(s, p)| (s, Space::Lps.convert_point(Space::Ras, p)))
            .collect(),
    };
    Ok(Labelled { points, frame: Space::Ras })
}

/// `.fcsv`: `#` comment lines (one of them `# CoordinateSystem = RAS|LPS|0|1`), then
/// `id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,…`.
fn read_fcsv(f: &Path) -> Result<Labelled, String> {
    let text = read_text(f)?;
    let mut frame = Space::Ras;
    let mut points = Vec::new();
    for (l, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if let Some(c) = line.strip_prefix('#') {
            if let Some((key, value)) = c.split_once('=')
                && key.trim().eq_ignore_ascii_case("CoordinateSystem")
            {
                frame = match value.trim() {
                    "RAS" | "0" => Space::Ras,
                    "LPS" | "1" => Space::Lps,
                    v => {
                        return Err(format!(
                            "{}: line {}: unknown coordinate system '{v}' (RAS or LPS)",
                            f.display(),
                            l + 1
                        ));
                    }
                };
            }
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() < 12 {
            return Err(format!(
                "{}: line {}: a markups row has at least 12 columns \
                 (id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label), found {}",
                f.display(),
                l + 1,
                fields.len()
            ));
        }
        let v = numbers(f, l + 1, &fields[1..4])?;
        points.push((fields[11].trim().to_string(), Point3::new(v[0], v[1], v[2])));
    }
    Ok(Labelled { points, frame })
}

/// `.mrk.json`: `markups[0].coordinateSystem` and `markups[0].controlPoints[*]` with
/// `label` and `position`.
fn read_mrk_json(f: &Path) -> Result<Labelled, String> {
    let text = read_text(f)?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", f.display()))?;
    let markup = json.get("markups").and_then(|m| m.get(0)).ok_or_else(|| {
        format!("{}: no \"markups\" list: not a 3D Slicer markups file", f.display())
    })?;
    let frame = match markup.get("coordinateSystem").and_then(|c| c.as_str()).unwrap_or("LPS") {
        "RAS" => Space::Ras,
        "LPS" => Space::Lps,
        v => return Err(format!("{}: unknown coordinateSystem '{v}' (RAS or LPS)", f.display())),
    };
    let list = markup
        .get("controlPoints")
        .and_then(|c| c.as_array())
        .ok_or_else(|| format!("{}: markups[0] has no \"controlPoints\" list", f.display()))?;
    let mut points = Vec::new();
    for (i, c) in list.iter().enumerate() {
        let label = c.get("label").and_then(|l| l.as_str()).unwrap_or_default().to_string();
        let position: Option<Vec<f64>> = c
            .get("position")
            .and_then(|p| p.as_array())
            .map(|a| a.iter().filter_map(|v| v.as_f64()).collect());
        match position {
            Some(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => {
                points.push((label, Point3::new(v[0], v[1], v[2])));
            }
            _ => {
                return Err(format!(
                    "{}: control point {} (label \"{label}\"): \"position\" must be three \
                     finite numbers",
                    f.display(),
                    i + 1
                ));
            }
        }
    }
    Ok(Labelled { points, frame })
}

/// Pairs the points of two markups files by label (RAS).
fn pair_by_label(fa: &Path, a: &Labelled, fb: &Path, b: &Labelled) -> Result<Pairs, String> {
    let mut pairs = Pairs::default();
    for (label, p) in &a.points {
        if label.is_empty() {
            return Err(format!("{}: a control point has no label to pair it by", fa.display()));
        }
        if a.points.iter().filter(|(l, _)| l == label).count() > 1 {
            return Err(format!("{}: label \"{label}\" appears twice", fa.display()));
        }
        let Some((_, q)) = b.points.iter().find(|(l, _)| l == label) else {
            return Err(format!(
                "{}: label \"{label}\" has no point of that label in {}",
                fa.display(),
                fb.display()
            ));
        };
        pairs.pre.push(*p);
        pairs.intra.push(*q);
        pairs.origin.push(format!("label \"{label}\""));
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("bs-pairs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn every_format_gives_the_same_pairs_in_the_scenes_frame() {
        let csv = write("a.csv", "x,y,z,x2,y2,z2\n1,2,3,1.5,2,2\n-4,5,6,-4,5.5,6\n");
        let tag = write(
            "a.tag",
            "MNI Tag Point File\nVolumes = 2;\n% comment\n\nPoints =\n 1 2 3 1.5 2 2 \"a\"\n \
             -4 5 6 -4 5.5 6 1 1 1 \"b\";\n",
        );
        let pre = write(
            "pre.fcsv",
            "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n\
             # columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n\
             a,-1,-2,3,0,0,0,1,1,1,0,F-1,,\nb,4,-5,6,0,0,0,1,1,1,0,F-2,,\n",
        );
        let intra = write(
            "intra.mrk.json",
            r#"{"markups":[{"type":"Fiducial","coordinateSystem":"RAS","controlPoints":[
                {"label":"F-2","position":[-4,5.5,6]},{"label":"F-1","position":[1.5,2,2]}]}]}"#,
        );
        let expect_pre = [Point3::new(1.0, 2.0, 3.0), Point3::new(-4.0, 5.0, 6.0)];
        let expect_intra = [Point3::new(1.5, 2.0, 2.0), Point3::new(-4.0, 5.5, 6.0)];
        for files in [
            LandmarkFiles::Pairs(csv.clone()),
            LandmarkFiles::Pairs(tag),
            LandmarkFiles::Split([pre, intra]),
        ] {
            let p = read_pairs(&files, Space::Ras).unwrap();
            assert_eq!(p.pre, expect_pre, "{files:?}");
            assert_eq!(p.intra, expect_intra, "{files:?}");
        }
        // CSV is in the scene's frame already; RAS files are flipped into an LPS scene.
        let lps = read_pairs(&LandmarkFiles::Pairs(csv), Space::Lps).unwrap();
        assert_eq!(lps.pre, expect_pre);
    }

    #[test]
    fn errors_name_the_file_and_line_or_label() {
        let bad = write("bad.csv", "x,y,z,x2,y2,z2\n1,2,3,4,5,6\n1,2,nan,4,5,6\n");
        let e = read_pairs(&LandmarkFiles::Pairs(bad), Space::Ras).unwrap_err();
        assert!(e.contains("bad.csv: line 3") && e.contains("nan"), "{e}");
        let one = write("one.tag", "MNI Tag Point File\nVolumes = 1;\nPoints =\n 1 2 3;\n");
        let e = read_pairs(&LandmarkFiles::Pairs(one), Space::Ras).unwrap_err();
        assert!(e.contains("line 4") && e.contains("Volumes = 2"), "{e}");
        let a = write(
            "a.mrk.json",
            r#"{"markups":[{"controlPoints":[{"label":"X","position":[0,0,0]}]}]}"#,
        );
        let b = write(
            "b.mrk.json",
            r#"{"markups":[{"controlPoints":[{"label":"Y","position":[0,0,0]}]}]}"#,
        );
        let e = read_pairs(&LandmarkFiles::Split([a, b]), Space::Ras).unwrap_err();
        assert!(e.contains("label \"X\" has no point"), "{e}");
        let empty = write("empty.csv", "x,y,z,x2,y2,z2\n");
        let e = read_pairs(&LandmarkFiles::Pairs(empty), Space::Ras).unwrap_err();
        assert!(e.contains("no landmark pairs"), "{e}");
    }
}
