//! `brainshift inspect FILE`: what a mesh file holds and whether it is usable.

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

use bs_mesh::io::{self, MeshFile};
use bs_mesh::quality::{self, Stats};
use bs_mesh::{Mesh, SurfaceCheck, TriSurface};
use serde::Serialize;

#[derive(Debug, Serialize)]
struct Report {
    file: String,
    kind: &'static str,
    nodes: usize,
    elements: Elements,
    node_sets: Vec<SetInfo>,
    element_sets: Vec<SetInfo>,
    bounding_box: Option<[[f64; 3]; 2]>,
    quality: Option<Quality>,
    surface: Option<SurfaceInfo>,
    unused_nodes: usize,
    problems: Vec<String>,
    valid: bool,
}

#[derive(Debug, Serialize, Default)]
struct Elements {
    tet4: usize,
    hex8: usize,
    triangles: usize,
}

#[derive(Debug, Serialize)]
struct SetInfo {
    name: String,
    size: usize,
}

#[derive(Debug, Serialize)]
struct Quality {
    tet_radius_ratio: Option<StatsOut>,
    hex_scaled_jacobian: Option<StatsOut>,
    inverted: usize,
}

#[derive(Debug, Serialize)]
struct StatsOut {
    min: f64,
    median: f64,
    max: f64,
}

impl From<Stats> for StatsOut {
    fn from(s: Stats) -> Self {
        StatsOut { min: s.min, median: s.median, max: s.max }
    }
}

#[derive(Debug, Serialize)]
struct SurfaceInfo {
    /// "boundary" (extracted from the volume mesh) or "file".
    source: &'static str,
    vertices: usize,
    triangles: usize,
    closed: bool,
    manifold: bool,
    consistently_oriented: bool,
    orientation: &'static str,
    euler_characteristic: i64,
    components: usize,
    enclosed_volume: f64,
    degenerate_triangles: usize,
    /// Pairs of triangles that cross each other, and one of them.
    self_intersections: usize,
    self_intersection_example: Option<[usize; 2]>,
}

impl SurfaceInfo {
    fn new(source: &'static str, c: &SurfaceCheck) -> Self {
        let consistently_oriented = c.misoriented_edges == 0;
        let orientation = match (c.boundary_edges == 0 && consistently_oriented, c.signed_volume) {
            // No triangles (an empty mesh) have no orientation; -0 volume is not "inward".
            _ if c.triangles == 0 => "undefined",
            (false, _) => "undefined",
            (true, v) if v > 0.0 => "outward",
            (true, _) => "inward",
        };
        SurfaceInfo {
            source,
            vertices: c.vertices,
            triangles: c.triangles,
            closed: c.boundary_edges == 0,
            manifold: c.non_manifold_edges == 0 && c.non_manifold_vertices == 0,
            consistently_oriented,
            orientation,
            euler_characteristic: c.euler_characteristic,
            components: c.components,
            enclosed_volume: c.signed_volume,
            degenerate_triangles: c.degenerate_triangles,
            self_intersections: c.self_intersections.len(),
            self_intersection_example: c.self_intersections.first().map(|p| [p.first, p.second]),
        }
    }

    fn problems(&self, what: &str) -> Vec<String> {
        let mut p = Vec::new();
        if !self.closed {
            p.push(format!("{what} is open (has holes); close them or remesh"));
        }
        if !self.manifold {
            p.push(format!("{what} is not manifold; split touching parts or remesh"));
        }
        if !self.consistently_oriented {
            p.push(format!("{what} is not consistently oriented; reorient its triangles"));
        }
        if self.orientation == "inward" {
            p.push(format!("{what} is oriented inward; flip every triangle"));
        }
        if self.degenerate_triangles > 0 {
            p.push(format!("{what} has {} zero-area triangles; remesh", self.degenerate_triangles));
        }
        if let Some([a, b]) = self.self_intersection_example {
            p.push(format!(
                "{what} intersects itself: {} pairs of triangles cross (e.g. triangles {a} and \
                 {b}); repair or remesh it into one closed shell that does not cross itself",
                self.self_intersections
            ));
        }
        p
    }
}

fn sets(map: &std::collections::BTreeMap<String, Vec<usize>>) -> Vec<SetInfo> {
    map.iter().map(|(name, v)| SetInfo { name: name.clone(), size: v.len() }).collect()
}

fn bbox(b: Option<(bs_mesh::Point3<f64>, bs_mesh::Point3<f64>)>) -> Option<[[f64; 3]; 2]> {
    b.map(|(lo, hi)| [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]])
}

fn volume_report(file: &Path, mesh: &Mesh) -> Report {
    let v = mesh.validate();
    let mut problems: Vec<String> = v.errors.iter().map(ToString::to_string).collect();
    let (tet4, hex8) = mesh.count_by_kind();
    let q = quality::summary(mesh);
    // The boundary is only meaningful when element indices are in range.
    let surface = v
        .errors
        .iter()
        .all(|e| !matches!(e, bs_mesh::MeshError::NodeOutOfRange { .. }))
        .then(|| mesh.boundary().surface.check().ok())
        .flatten()
        .map(|c| SurfaceInfo::new("boundary", &c));
    if let Some(s) = &surface {
        problems.extend(s.problems("the boundary surface"));
    }
    Report {
        file: file.display().to_string(),
        kind: "volume",
        nodes: mesh.nodes.len(),
        elements: Elements { tet4, hex8, triangles: 0 },
        node_sets: sets(&mesh.node_sets),
        element_sets: sets(&mesh.element_sets),
        bounding_box: bbox(mesh.bounding_box()),
        quality: Some(Quality {
            tet_radius_ratio: q.tet_radius_ratio.map(Into::into),
            hex_scaled_jacobian: q.hex_scaled_jacobian.map(Into::into),
            inverted: q.inverted,
        }),
        surface,
        unused_nodes: v.unused_node_ids.len(),
        valid: problems.is_empty(),
        problems,
    }
}

fn surface_report(file: &Path, s: &TriSurface) -> Report {
    let (surface, unused_nodes, mut problems) = match s.check() {
        Ok(c) => {
            let info = SurfaceInfo::new("file", &c);
            let p = info.problems("the surface");
            (Some(info), c.unused_vertices, p)
        }
        Err(e) => (None, 0, vec![e.to_string()]),
    };
    if s.triangles.is_empty() {
        problems.push("the surface has no triangles".into());
    }
    Report {
        file: file.display().to_string(),
        kind: "surface",
        nodes: s.vertices.len(),
        elements: Elements { triangles: s.triangles.len(), ..Default::default() },
        node_sets: Vec::new(),
        element_sets: Vec::new(),
        bounding_box: bbox(s.bounding_box()),
        quality: None,
        unused_nodes,
        surface,
        valid: problems.is_empty(),
        problems,
    }
}

fn text(r: &Report) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "{} ({} mesh)", r.file, r.kind);
    let _ = writeln!(o, "  nodes:          {}", r.nodes);
    if r.kind == "volume" {
        let _ = writeln!(
            o,
            "  elements:       {} (tet4: {}, hex8: {})",
            r.elements.tet4 + r.elements.hex8,
            r.elements.tet4,
            r.elements.hex8
        );
    } else {
        let _ = writeln!(o, "  triangles:      {}", r.elements.triangles);
    }
    for (label, sets) in [("node sets", &r.node_sets), ("element sets", &r.element_sets)] {
        if !sets.is_empty() {
            let list: Vec<String> =
                sets.iter().map(|s| format!("{} ({})", s.name, s.size)).collect();
            let _ = writeln!(o, "  {label:<15} {}", list.join(", "));
        }
    }
    if let Some([lo, hi]) = r.bounding_box {
        let _ = writeln!(
            o,
            "  bounding box:   [{:.6}, {:.6}, {:.6}] .. [{:.6}, {:.6}, {:.6}] (size {:.6} x {:.6} x {:.6})",
            lo[0],
            lo[1],
            lo[2],
            hi[0],
            hi[1],
            hi[2],
            hi[0] - lo[0],
            hi[1] - lo[1],
            hi[2] - lo[2]
        );
    }
    if let Some(q) = &r.quality {
        if let Some(s) = &q.tet_radius_ratio {
            let _ = writeln!(
                o,
                "  tet radius ratio (1 = regular): min {:.4}, median {:.4}",
                s.min, s.median
            );
        }
        if let Some(s) = &q.hex_scaled_jacobian {
            let _ = writeln!(
                o,
                "  hex scaled Jacobian (1 = cube): min {:.4}, median {:.4}",
                s.min, s.median
            );
        }
        let _ = writeln!(o, "  inverted elements: {}", q.inverted);
    }
    if let Some(s) = &r.surface {
        let _ = writeln!(
            o,
            "  surface ({}): {} vertices, {} triangles, {}, {}, {}{} (Euler characteristic {}, {} component{}, enclosed volume {:.6})",
            s.source,
            s.vertices,
            s.triangles,
            if s.closed { "closed" } else { "OPEN" },
            if s.manifold { "manifold" } else { "NON-MANIFOLD" },
            match s.orientation {
                "outward" => "oriented outward",
                "inward" => "oriented INWARD",
                _ => "orientation undefined",
            },
            if s.self_intersections > 0 { ", SELF-INTERSECTING" } else { "" },
            s.euler_characteristic,
            s.components,
            if s.components == 1 { "" } else { "s" },
            s.enclosed_volume
        );
    }
    if r.unused_nodes > 0 {
        let _ = writeln!(o, "  unused nodes:   {} (ignored by the solver)", r.unused_nodes);
    }
    if r.valid {
        let _ = writeln!(o, "  status: OK");
    } else {
        let _ = writeln!(
            o,
            "  status: INVALID ({} problem{})",
            r.problems.len(),
            if r.problems.len() == 1 { "" } else { "s" }
        );
        for p in r.problems.iter().take(20) {
            let _ = writeln!(o, "    - {p}");
        }
        if r.problems.len() > 20 {
            let _ = writeln!(o, "    ... and {} more", r.problems.len() - 20);
        }
    }
    o
}

/// Runs `inspect`; returns the exit code (failure when the mesh is unusable).
pub fn run(file: &Path, json: bool) -> Result<ExitCode, io::MeshIoError> {
    let report = match io::read(file)? {
        MeshFile::Volume(mesh, _) => volume_report(file, &mesh),
        MeshFile::Surface(s) => surface_report(file, &s),
    };
    if json {
        let json = serde_json::to_string_pretty(&report).expect("report serialises");
        crate::emit(&format!("{json}\n"));
    } else {
        crate::emit(&text(&report));
    }
    if let (false, Some(first)) = (report.valid, report.problems.first()) {
        // The report went to standard output; say why the exit status is 1 where errors go.
        let n = report.problems.len();
        eprintln!(
            "error: {}: the mesh is not usable ({n} problem{}); first: {first}",
            file.display(),
            if n == 1 { "" } else { "s" }
        );
    }
    Ok(if report.valid { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}
