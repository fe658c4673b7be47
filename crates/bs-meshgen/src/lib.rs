//! Meshes from segmentations (labelmaps) for brainshift.
//!
//! [`mesh_labelmap`] turns a labelmap ([`Volume<u32>`]) into a brain mesh with element sets
//! per region and the node sets `FIXED` (the inferior-most surface nodes, the brain stem's
//! cut) and `CRANIOTOMY` (surface nodes near the top), plus a closed outward skull cavity
//! surface around it:
//!
//! * [`implicit`]: smoothed indicator fields from the labels (separable Gaussian),
//!   trilinear evaluation at world points;
//! * [`bcc`], [`stuffing`], [`stencil`]: isosurface stuffing on a BCC lattice (Labelle &
//!   Shewchuk 2007), dihedral angles proven in [10.78°, 164.76°];
//! * [`regions`]: region surfaces cut into the stuffed brain, conforming on both sides;
//! * [`hex`]: voxel-like hexahedra on a grid;
//! * [`cavity`] (with [`edt`]): the skull cavity by offset-and-closing of the brain mask, or
//!   the inside of a skull label;
//! * [`quality`], [`report`]: dihedral angles and the [`MeshReport`].
//!
//! Coordinates are the image's world frame in mm (RAS for NIfTI), as given by the
//! labelmap's [`Grid`](bs_image::Grid).
//!
//! *Architecture invariant:* bs-meshgen knows images and meshes; it knows no materials,
//! solvers, contact or scene files.

pub mod bcc;
pub mod cavity;
pub mod edt;
mod error;
pub mod hex;
pub mod implicit;
pub mod quality;
pub mod regions;
pub mod report;
pub mod stencil;
pub mod stuffing;

use std::collections::BTreeSet;
use std::time::Instant;

use bs_image::Volume;
use bs_mesh::{Element, Mesh, Point3, TriSurface, Vector3};
use rayon::prelude::*;

pub use error::MeshgenError;
pub use report::{MeshReport, RegionVolume};

use crate::implicit::{SampledField, WorkGrid, bounding_box, gaussian_blur, world_box};
use crate::stuffing::{Fill, MAX_DIHEDRAL_BOUND_DEG, MIN_DIHEDRAL_BOUND_DEG, stuff};

/// Element type of the brain mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ElementType {
    /// Quality tetrahedra by isosurface stuffing (the default).
    #[default]
    T4,
    /// Hexahedra on a regular grid.
    H8,
}

impl ElementType {
    /// `"t4"` or `"h8"`.
    pub fn name(self) -> &'static str {
        match self {
            ElementType::T4 => "t4",
            ElementType::H8 => "h8",
        }
    }

    /// Parses `"t4"` / `"h8"` (case-insensitive).
    pub fn from_name(s: &str) -> Option<ElementType> {
        match s.to_ascii_lowercase().as_str() {
            "t4" => Some(ElementType::T4),
            "h8" => Some(ElementType::H8),
            _ => None,
        }
    }
}

/// A region with its own material: an element set made of the elements on these labels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RegionSpec {
    /// Element set name (written as given, e.g. `VENTRICLES`).
    pub name: String,
    /// Label values.
    pub labels: Vec<u32>,
}

/// The name of the element set holding the brain outside every region.
pub const BRAIN_SET: &str = "BRAIN";
/// The node set held fixed (the inferior-most brain surface, the brain stem's cut).
pub const FIXED_SET: &str = "FIXED";
/// The node set of surface nodes near the top of the brain, for a craniotomy load.
pub const CRANIOTOMY_SET: &str = "CRANIOTOMY";

/// Largest lattice (or grid) size accepted: 50 million vertices, about 2 GB of working
/// memory and far beyond any brain model (1 mm over MNI152 is 9 million).
pub const MAX_LATTICE_VERTICES: f64 = 50e6;

/// How to mesh a labelmap.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshParams {
    /// Labels making up the brain; `None` = every non-zero label.
    pub brain_labels: Option<Vec<u32>>,
    /// Regions with their own material (the rest of the brain is [`BRAIN_SET`]).
    pub regions: Vec<RegionSpec>,
    /// Target edge length, mm: the BCC lattice spacing (long edges; short edges are 0.87×)
    /// or the hexahedron side.
    pub size: f64,
    /// Element type.
    pub element: ElementType,
    /// Distance of the skull cavity outside the brain, mm (ignored with `cavity_labels`);
    /// for H8 measured from the staircase's outer corners (offset + √3/2 `size` from the
    /// smooth brain surface).
    pub skull_offset: f64,
    /// Radius of the ball the offset brain is closed with, mm: the cavity bridges sulci.
    pub closing_radius: f64,
    /// If given, the cavity is the inside of these (skull) labels instead of an offset.
    pub cavity_labels: Option<Vec<u32>>,
    /// Standard deviation of the Gaussian smoothing the indicator, mm; `None` = 0.6 × the
    /// largest voxel size. The blur damps the voxel staircase (a 45° staircase's ripple by
    /// e^(−2π²σ²) ≈ 10⁻³) but moves the ½ level inwards by about σ² × mean curvature (mean
    /// curvature flow for time σ²/2): for a 20 mm ball in 1 mm voxels, −0.3% of volume.
    pub smoothing: Option<f64>,
    /// Lattice spacing of the skull surface, mm; `None` = `size`.
    pub skull_size: Option<f64>,
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            brain_labels: None,
            regions: Vec::new(),
            size: 4.0,
            element: ElementType::T4,
            skull_offset: 3.0,
            closing_radius: 5.0,
            cavity_labels: None,
            smoothing: None,
            skull_size: None,
        }
    }
}

/// A meshed labelmap.
#[derive(Debug, Clone)]
pub struct Meshed {
    /// The brain: element sets [`BRAIN_SET`] and one per region, node sets [`FIXED_SET`]
    /// and [`CRANIOTOMY_SET`]; world coordinates in mm.
    pub mesh: Mesh,
    /// The skull cavity: closed, outward, without self-intersections, the brain inside.
    pub skull: TriSurface,
    /// Measurements.
    pub report: MeshReport,
}

fn check_params(labels: &Volume<u32>, p: &MeshParams) -> Result<(), MeshgenError> {
    let positive = |name: &'static str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(MeshgenError::Param {
                name,
                message: format!("{v} must be a positive number of mm"),
            })
        }
    };
    positive("--size", p.size)?;
    positive("--skull-offset", p.skull_offset)?;
    positive("closing radius", p.closing_radius)?;
    if let Some(s) = p.smoothing.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(MeshgenError::Param {
            name: "smoothing",
            message: format!("{s} must be ≥ 0 mm"),
        });
    }
    if let Some(s) = p.skull_size {
        positive("skull size", s)?;
    }
    let extent = {
        let (lo, hi) = world_box(&labels.grid);
        (hi - lo).norm()
    };
    if p.size > extent {
        return Err(MeshgenError::Param {
            name: "--size",
            message: format!(
                "{} mm exceeds the image's extent ({extent:.0} mm); give a smaller size",
                p.size
            ),
        });
    }
    if p.brain_labels.as_ref().is_some_and(|b| b.contains(&0)) {
        return Err(MeshgenError::Labels(
            "label 0 is the background and cannot be part of --brain; list the brain's label values".into(),
        ));
    }
    let mut seen = BTreeSet::new();
    let mut names = BTreeSet::new();
    for r in &p.regions {
        if r.name.is_empty()
            || !r.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "a region name must be non-empty letters, digits, '_' or '-' (it names an element set)".into(),
            });
        }
        if r.name.eq_ignore_ascii_case(BRAIN_SET) || !names.insert(r.name.to_ascii_uppercase()) {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "the name is used twice (BRAIN is the rest of the brain); give each region its own name".into(),
            });
        }
        if r.labels.is_empty() {
            return Err(MeshgenError::Region {
                region: r.name.clone(),
                message: "no labels given; write NAME=4 or NAME=4,5".into(),
            });
        }
        for &l in &r.labels {
            if l == 0 {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: "label 0 is the background".into(),
                });
            }
            if p.brain_labels.as_ref().is_some_and(|b| !b.contains(&l)) {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: format!("label {l} is not part of --brain; add it to --brain"),
                });
            }
            if !seen.insert(l) {
                return Err(MeshgenError::Region {
                    region: r.name.clone(),
                    message: format!("label {l} belongs to two regions; give it to one"),
                });
            }
        }
    }
    Ok(())
}

/// Labels present in the image and their voxel counts (for error messages and volumes).
fn label_counts(labels: &Volume<u32>) -> std::collections::BTreeMap<u32, usize> {
    labels
        .data
        .par_chunks(1 << 16)
        .fold(std::collections::BTreeMap::new, |mut m, chunk| {
            for &l in chunk {
                *m.entry(l).or_insert(0usize) += 1;
            }
            m
        })
        .reduce(std::collections::BTreeMap::new, |mut a, b| {
            for (k, v) in b {
                *a.entry(k).or_insert(0) += v;
            }
            a
        })
}

/// Meshes the brain of a labelmap and builds its skull cavity (see the crate docs).
pub fn mesh_labelmap(labels: &Volume<u32>, params: &MeshParams) -> Result<Meshed, MeshgenError> {
    let mut timings = Vec::new();
    let mut clock = Instant::now();
    let mut lap = |name: &'static str, timings: &mut Vec<(&'static str, f64)>| {
        timings.push((name, clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    check_params(labels, params)?;
    let counts = label_counts(labels);
    let present: Vec<u32> = counts.keys().copied().filter(|&l| l != 0).collect();
    let in_brain = |l: u32| match &params.brain_labels {
        Some(b) => b.contains(&l),
        None => l != 0,
    };
    let wanted: Vec<u32> = params
        .brain_labels
        .iter()
        .flatten()
        .chain(params.regions.iter().flat_map(|r| &r.labels))
        .chain(params.cavity_labels.iter().flatten())
        .copied()
        .collect();
    if let Some(l) = wanted.iter().find(|l| !counts.contains_key(l)) {
        return Err(MeshgenError::Labels(format!(
            "label {l} does not occur in the image (labels present: {present:?})"
        )));
    }
    let brain_voxels: usize = counts.iter().filter(|(l, _)| in_brain(**l)).map(|(_, c)| c).sum();
    if brain_voxels == 0 {
        return Err(MeshgenError::Labels(format!(
            "the brain is empty (labels present: {present:?}); give its labels with --brain"
        )));
    }
    let voxel_volume = labels.grid.voxel_volume();
    let spacing = labels.grid.spacing();
    let max_spacing = spacing.iter().copied().fold(0.0, f64::max);
    let min_spacing = spacing.iter().copied().fold(f64::INFINITY, f64::min);
    let sigma = params.smoothing.unwrap_or(0.6 * max_spacing);
    let skull_h = params.skull_size.unwrap_or(params.size);

    // Working grid: the brain's voxels plus room for the smoothing, the cavity and the
    // lattices' padding.
    let (blo, bhi) = bounding_box(labels, in_brain).expect("non-empty brain");
    let margin_mm = params.closing_radius
        + params.skull_offset
        + params.size
        + 4.0 * sigma
        + 2.0 * params.size.max(skull_h)
        + 3.0 * max_spacing;
    let pad = (margin_mm / min_spacing).ceil() as i64;
    let work = WorkGrid::new(&labels.grid, blo.map(|x| x - pad), bhi.map(|x| x + pad));
    let sigma_vox = spacing.map(|s| sigma / s);
    let raw_brain = work.indicator(labels, in_brain);
    let mut smooth = raw_brain.clone();
    gaussian_blur(&mut smooth, work.dims(), sigma_vox);
    let brain = SampledField { grid: work.grid.clone(), data: smooth, outside: 0.0, level: 0.5 };
    let region_fields: Vec<SampledField> = params
        .regions
        .iter()
        .map(|r| {
            let mut d = work.indicator(labels, |l| r.labels.contains(&l));
            gaussian_blur(&mut d, work.dims(), sigma_vox);
            SampledField { grid: work.grid.clone(), data: d, outside: 0.0, level: 0.5 }
        })
        .collect();
    lap("fields", &mut timings);

    // The brain's world box (voxel corners of its bounding box, plus the smoothing).
    let inner = WorkGrid::new(&labels.grid, blo.map(|x| x - 1), bhi.map(|x| x + 1));
    let (mut lo, mut hi) = world_box(&inner.grid);
    lo -= Vector3::repeat(2.0 * sigma);
    hi += Vector3::repeat(2.0 * sigma);
    // Lattice sizes are bounded before anything is allocated (node ids are 32-bit and a
    // 0.1 mm lattice over a brain would need tens of GB).
    for (name, h, extra) in [
        ("--size", params.size, 0.0),
        ("skull size", skull_h, 2.0 * (params.skull_offset + params.closing_radius + params.size)),
    ] {
        let cells: f64 = (0..3).map(|a| (hi[a] - lo[a] + extra) / h + 4.0).product();
        if 2.0 * cells > MAX_LATTICE_VERTICES {
            let smallest = h * (2.0 * cells / MAX_LATTICE_VERTICES).cbrt();
            return Err(MeshgenError::Param {
                name,
                message: format!(
                    "{h} mm needs about {:.0} million lattice vertices over the brain (limit {:.0} million); give at least {smallest:.2} mm",
                    2.0 * cells / 1e6,
                    MAX_LATTICE_VERTICES / 1e6
                ),
            });
        }
    }
    let f = |p: &Point3<f64>| brain.eval(p);

    let (mut mesh, surface_nodes, labels_of, warped) = match params.element {
        ElementType::T4 => {
            let mut s = stuff(&f, lo, hi, params.size, Fill::All);
            lap("stuffing", &mut timings);
            let lab = if region_fields.is_empty() {
                vec![0u8; s.tets.len()]
            } else {
                let l = regions::split(&mut s, &region_fields);
                lap("regions", &mut timings);
                l
            };
            let surface: Vec<usize> = (0..s.nodes.len()).filter(|&i| s.on_surface[i]).collect();
            let elements = s.tets.iter().map(|t| Element::tet4(t.map(|v| v as usize))).collect();
            (Mesh::new(s.nodes, elements), surface, lab, s.warped)
        }
        ElementType::H8 => {
            let rf: Vec<_> =
                region_fields.iter().map(|r| move |p: &Point3<f64>| r.eval(p)).collect();
            let g = hex::hex_grid(&f, &rf, lo, hi, params.size);
            let elements = g.hexes.iter().map(|h| Element::hex8(*h)).collect();
            let mesh = Mesh::new(g.nodes, elements);
            let surface = mesh.boundary().volume_node;
            lap("hexahedra", &mut timings);
            (mesh, surface, g.label, 0)
        }
    };
    if mesh.elements.is_empty() {
        return Err(MeshgenError::Check {
            what: "brain mesh",
            message: format!(
                "no element: the brain ({brain_voxels} voxels) is thinner than --size {} mm; give a smaller --size",
                params.size
            ),
        });
    }
    // Element sets.
    let mut names = vec![BRAIN_SET.to_string()];
    names.extend(params.regions.iter().map(|r| r.name.to_ascii_uppercase()));
    for (k, name) in names.iter().enumerate() {
        let set: Vec<usize> =
            (0..labels_of.len()).filter(|&e| labels_of[e] as usize == k).collect();
        if !set.is_empty() {
            mesh.element_sets.insert(name.clone(), set);
        }
    }
    let (fixed, craniotomy) = load_sets(&mesh, &surface_nodes, params.size);
    mesh.node_sets.insert(FIXED_SET.into(), fixed);
    mesh.node_sets.insert(CRANIOTOMY_SET.into(), craniotomy);
    let quality = quality::stats(&mesh);
    if quality.inverted > 0 {
        return Err(MeshgenError::Check {
            what: "brain mesh",
            message: format!(
                "{} inverted or flat elements; try a smaller --size or more smoothing",
                quality.inverted
            ),
        });
    }
    lap("sets and quality", &mut timings);

    // Skull cavity. Hexahedra whose centre is inside reach up to half a cell diagonal
    // (√3/2 h) beyond the brain's surface: their cavity is offset from there.
    let offset = match params.element {
        ElementType::T4 => params.skull_offset,
        ElementType::H8 => params.skull_offset + 0.5 * 3f64.sqrt() * params.size,
    };
    let cavity = match &params.cavity_labels {
        None => {
            // The cavity needs no finer field than half its lattice spacing; blocks of at
            // most 2 voxels (3-voxel blocks cost up to 1.5 mm of the gap on MNI152 at 6 mm).
            let coarsen = ((skull_h / (2.0 * max_spacing)).floor() as usize).clamp(1, 2);
            cavity::offset_field(&work, &raw_brain, offset, params.closing_radius, coarsen)
        }
        Some(sk) => {
            let skull_ind = work.indicator(labels, |l| sk.contains(&l));
            cavity::enclosed_field(&work, &skull_ind, sigma_vox)
        }
    };
    let reach = offset + params.closing_radius + 2.0 * skull_h;
    let (clo, chi) = match &params.cavity_labels {
        None => (lo - Vector3::repeat(reach), hi + Vector3::repeat(reach)),
        Some(_) => world_box(&work.grid),
    };
    let skull = cavity::surface(&cavity, clo, chi, skull_h);
    lap("cavity", &mut timings);
    let check = skull
        .check()
        .map_err(|e| MeshgenError::Check { what: "skull surface", message: e.to_string() })?;
    if !check.is_closed_outward() || !check.self_intersections.is_empty() || check.components != 1 {
        return Err(MeshgenError::Check {
            what: "skull surface",
            message: format!(
                "not one closed outward surface without self-intersections ({} boundary edges, {} non-manifold edges, {} non-manifold vertices, {} misoriented edges, {} self-intersections, {} components, enclosed volume {:.0} mm³); try a larger closing radius or --skull-offset",
                check.boundary_edges,
                check.non_manifold_edges,
                check.non_manifold_vertices,
                check.misoriented_edges,
                check.self_intersections.len(),
                check.components,
                check.signed_volume
            ),
        });
    }
    // Brain inside the cavity, with the gap estimated from the cavity field.
    let depth: Vec<f64> = surface_nodes.par_iter().map(|&v| cavity.eval(&mesh.nodes[v])).collect();
    let worst = depth
        .iter()
        .copied()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |a, (i, d)| if d > a.1 { (i, d) } else { a });
    if worst.1 >= 0.0 {
        let p = mesh.nodes[surface_nodes[worst.0]];
        return Err(MeshgenError::Check {
            what: "skull surface",
            message: format!(
                "brain surface node at ({:.1}, {:.1}, {:.1}) mm is not inside the skull cavity; {}",
                p.x,
                p.y,
                p.z,
                if params.cavity_labels.is_some() {
                    "the brain touches or crosses the --cavity labels: check the segmentation or use --skull-offset"
                } else {
                    "increase --skull-offset"
                }
            ),
        });
    }
    let min_gap_estimate = match params.cavity_labels {
        // The offset field is a distance (mm); the label indicator is not.
        None => -worst.1,
        Some(_) => f64::NAN,
    };
    lap("checks", &mut timings);

    // Volumes.
    let vol: Vec<f64> =
        (0..mesh.elements.len()).into_par_iter().map(|e| mesh.element_volume(e)).collect();
    let mesh_volume: f64 = vol.iter().sum();
    let mut regions_out = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let labels_k: Vec<u32> = if k == 0 {
            counts
                .keys()
                .copied()
                .filter(|&l| in_brain(l) && !params.regions.iter().any(|r| r.labels.contains(&l)))
                .collect()
        } else {
            params.regions[k - 1].labels.clone()
        };
        let label_volume =
            labels_k.iter().map(|l| counts.get(l).copied().unwrap_or(0)).sum::<usize>() as f64
                * voxel_volume;
        let (n, v) = (0..labels_of.len())
            .filter(|&e| labels_of[e] as usize == k)
            .fold((0, 0.0), |(n, v), e| (n + 1, v + vol[e]));
        regions_out.push(RegionVolume {
            name: name.clone(),
            elements: n,
            mesh_volume: v,
            label_volume,
        });
    }
    let report = MeshReport {
        element: params.element,
        size: params.size,
        nodes: mesh.nodes.len(),
        elements: mesh.elements.len(),
        quality,
        dihedral_bound_deg: (params.element == ElementType::T4)
            .then_some((MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG)),
        mesh_volume,
        label_volume: brain_voxels as f64 * voxel_volume,
        regions: regions_out,
        warped,
        fixed_nodes: mesh.node_sets[FIXED_SET].len(),
        craniotomy_nodes: mesh.node_sets[CRANIOTOMY_SET].len(),
        skull_vertices: skull.vertices.len(),
        skull_triangles: skull.triangles.len(),
        min_gap_estimate,
        timings,
    };
    Ok(Meshed { mesh, skull, report })
}

/// FIXED: surface nodes within one element size above the inferior-most surface point
/// (world −z is inferior in RAS) and within three sizes of it horizontally, at least 3.
/// CRANIOTOMY: surface nodes within min(30 mm, a quarter of the brain's extent) of the
/// superior-most surface point.
fn load_sets(mesh: &Mesh, surface: &[usize], size: f64) -> (Vec<usize>, Vec<usize>) {
    let z = |v: usize| mesh.nodes[v].z;
    let low =
        *surface.iter().min_by(|&&a, &&b| z(a).total_cmp(&z(b))).expect("a mesh has a surface");
    let high =
        *surface.iter().max_by(|&&a, &&b| z(a).total_cmp(&z(b))).expect("a mesh has a surface");
    let pl = mesh.nodes[low];
    let horizontal = |v: usize| {
        let d = mesh.nodes[v] - pl;
        (d.x * d.x + d.y * d.y).sqrt()
    };
    let mut fixed: Vec<usize> = surface
        .iter()
        .copied()
        .filter(|&v| z(v) <= pl.z + size && horizontal(v) <= 3.0 * size)
        .collect();
    if fixed.len() < 3 {
        let mut by_depth = surface.to_vec();
        by_depth
            .sort_by(|&a, &b| (mesh.nodes[a] - pl).norm().total_cmp(&(mesh.nodes[b] - pl).norm()));
        fixed = by_depth.into_iter().take(3).collect();
    }
    fixed.sort_unstable();
    let (blo, bhi) = mesh.bounding_box().expect("nodes");
    let extent = (bhi - blo).max();
    let radius = (0.25 * extent).min(30.0);
    let ph = mesh.nodes[high];
    let mut cran: Vec<usize> =
        surface.iter().copied().filter(|&v| (mesh.nodes[v] - ph).norm() <= radius).collect();
    cran.sort_unstable();
    (fixed, cran)
}
