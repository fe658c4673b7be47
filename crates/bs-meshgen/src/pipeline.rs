//! `mesh_labelmap` as named phases: the labels checked and counted, the smoothed fields on
//! a working grid, the lattice's box and size bound, the volume mesh (stuffed tetrahedra or
//! hexahedra), its sets and quality, the skull cavity and its checks, and the volumes the
//! report compares with the labels.

use std::collections::BTreeMap;
use std::time::Instant;

use bs_image::Volume;
use bs_mesh::{Element, Mesh, Point3, TriSurface, Vector3};
use rayon::prelude::*;

use crate::implicit::{SampledField, WorkGrid, bounding_box, gaussian_blur, world_box};
use crate::stuffing::{Fill, MAX_DIHEDRAL_BOUND_DEG, MIN_DIHEDRAL_BOUND_DEG, stuff};
use crate::{
    BRAIN_SET, CRANIOTOMY_SET, ElementType, FIXED_SET, MAX_LATTICE_VERTICES, MeshParams,
    MeshReport, Meshed, MeshgenError, RegionVolume, cavity, check_params, hex, quality, regions,
};

/// Each phase's wall time, in order.
struct Laps {
    clock: Instant,
    list: Vec<(&'static str, f64)>,
}

impl Laps {
    fn new() -> Self {
        Laps { clock: Instant::now(), list: Vec::new() }
    }

    fn lap(&mut self, name: &'static str) {
        self.list.push((name, self.clock.elapsed().as_secs_f64()));
        self.clock = Instant::now();
    }
}

/// Whether label `l` is brain: one of `--brain`'s labels, or any non-zero label.
fn in_brain(params: &MeshParams, l: u32) -> bool {
    match &params.brain_labels {
        Some(b) => b.contains(&l),
        None => l != 0,
    }
}

/// Meshes the brain of a labelmap and builds its skull cavity (see the crate docs).
pub fn mesh_labelmap(labels: &Volume<u32>, params: &MeshParams) -> Result<Meshed, MeshgenError> {
    let mut laps = Laps::new();
    check_params(labels, params)?;
    let counts = label_counts(labels);
    let brain_voxels = brain_voxel_count(&counts, params)?;
    let fields = Fields::new(labels, params);
    laps.lap("fields");
    let (lo, hi) = mesh_box(labels, &fields);
    check_lattice_sizes(lo, hi, params)?;
    let body = volume_mesh(&fields, params, lo, hi, brain_voxels, &mut laps)?;
    let mut mesh = body.mesh;
    let names = set_names(params);
    name_sets(&mut mesh, &names, &body.labels_of, &body.surface_nodes, params.size);
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
    laps.lap("sets and quality");
    let (cavity, skull) = skull_cavity(labels, params, &fields, lo, hi);
    laps.lap("cavity");
    check_skull(&skull)?;
    let min_gap_estimate = brain_inside(&mesh, &body.surface_nodes, &cavity, params)?;
    laps.lap("checks");
    let (mesh_volume, regions) = volumes(&mesh, &names, &body.labels_of, &counts, labels, params);
    let report = MeshReport {
        element: params.element,
        size: params.size,
        nodes: mesh.nodes.len(),
        elements: mesh.elements.len(),
        quality,
        dihedral_bound_deg: (params.element == ElementType::T4)
            .then_some((MIN_DIHEDRAL_BOUND_DEG, MAX_DIHEDRAL_BOUND_DEG)),
        mesh_volume,
        label_volume: brain_voxels as f64 * labels.grid.voxel_volume(),
        regions,
        warped: body.warped,
        fixed_nodes: mesh.node_sets[FIXED_SET].len(),
        craniotomy_nodes: mesh.node_sets[CRANIOTOMY_SET].len(),
        skull_vertices: skull.vertices.len(),
        skull_triangles: skull.triangles.len(),
        min_gap_estimate,
        timings: laps.list,
    };
    Ok(Meshed { mesh, skull, report })
}

/// Labels present in the image and their voxel counts (for error messages and volumes).
fn label_counts(labels: &Volume<u32>) -> BTreeMap<u32, usize> {
    labels
        .data
        .par_chunks(1 << 16)
        .fold(BTreeMap::new, |mut m, chunk| {
            for &l in chunk {
                *m.entry(l).or_insert(0usize) += 1;
            }
            m
        })
        .reduce(BTreeMap::new, |mut a, b| {
            for (k, v) in b {
                *a.entry(k).or_insert(0) += v;
            }
            a
        })
}

/// The brain's voxel count; every label the parameters name must occur in the image, and
/// the brain must not be empty.
fn brain_voxel_count(
    counts: &BTreeMap<u32, usize>,
    params: &MeshParams,
) -> Result<usize, MeshgenError> {
    let present: Vec<u32> = counts.keys().copied().filter(|&l| l != 0).collect();
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
    let brain_voxels: usize =
        counts.iter().filter(|(l, _)| in_brain(params, **l)).map(|(_, c)| c).sum();
    if brain_voxels == 0 {
        return Err(MeshgenError::Labels(format!(
            "the brain is empty (labels present: {present:?}); give its labels with --brain"
        )));
    }
    Ok(brain_voxels)
}

/// The smoothed indicator fields on a working grid around the brain.
struct Fields {
    /// The brain's voxels plus room for the smoothing, the cavity and the lattices' padding.
    work: WorkGrid,
    /// The brain's voxel bounding box (voxel indices, inclusive).
    brain_box: ([i64; 3], [i64; 3]),
    /// The brain's indicator before smoothing (the cavity's offset is measured from it).
    raw_brain: Vec<f32>,
    /// The smoothed brain, level 0.5.
    brain: SampledField,
    /// One smoothed field per region, level 0.5.
    region_fields: Vec<SampledField>,
    /// The Gaussian's width, mm and voxels per axis.
    sigma: f64,
    sigma_vox: [f64; 3],
}

impl Fields {
    fn new(labels: &Volume<u32>, params: &MeshParams) -> Self {
        let spacing = labels.grid.spacing();
        let max_spacing = spacing.iter().copied().fold(0.0, f64::max);
        let min_spacing = spacing.iter().copied().fold(f64::INFINITY, f64::min);
        let sigma = params.smoothing.unwrap_or(0.6 * max_spacing);
        let skull_h = params.skull_size.unwrap_or(params.size);
        let (blo, bhi) = bounding_box(labels, |l| in_brain(params, l)).expect("non-empty brain");
        let margin_mm = params.closing_radius
            + params.skull_offset
            + params.size
            + 4.0 * sigma
            + 2.0 * params.size.max(skull_h)
            + 3.0 * max_spacing;
        let pad = (margin_mm / min_spacing).ceil() as i64;
        let work = WorkGrid::new(&labels.grid, blo.map(|x| x - pad), bhi.map(|x| x + pad));
        let sigma_vox = spacing.map(|s| sigma / s);
        let raw_brain = work.indicator(labels, |l| in_brain(params, l));
        let mut smooth = raw_brain.clone();
        gaussian_blur(&mut smooth, work.dims(), sigma_vox);
        let brain =
            SampledField { grid: work.grid.clone(), data: smooth, outside: 0.0, level: 0.5 };
        let region_fields = params
            .regions
            .iter()
            .map(|r| {
                let mut d = work.indicator(labels, |l| r.labels.contains(&l));
                gaussian_blur(&mut d, work.dims(), sigma_vox);
                SampledField { grid: work.grid.clone(), data: d, outside: 0.0, level: 0.5 }
            })
            .collect();
        Fields { work, brain_box: (blo, bhi), raw_brain, brain, region_fields, sigma, sigma_vox }
    }
}

/// The box the lattices cover: the brain's voxel corners, plus the smoothing.
fn mesh_box(labels: &Volume<u32>, fields: &Fields) -> (Point3<f64>, Point3<f64>) {
    let (blo, bhi) = fields.brain_box;
    let sigma = fields.sigma;
    let inner = WorkGrid::new(&labels.grid, blo.map(|x| x - 1), bhi.map(|x| x + 1));
    let (mut lo, mut hi) = world_box(&inner.grid);
    lo -= Vector3::repeat(2.0 * sigma);
    hi += Vector3::repeat(2.0 * sigma);
    (lo, hi)
}

/// Lattice sizes are bounded before anything is allocated (node ids are 32-bit and a 0.1 mm
/// lattice over a brain would need tens of GB).
fn check_lattice_sizes(
    lo: Point3<f64>,
    hi: Point3<f64>,
    params: &MeshParams,
) -> Result<(), MeshgenError> {
    let skull_h = params.skull_size.unwrap_or(params.size);
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
    Ok(())
}

/// The volume mesh before its sets: its surface nodes, each element's region (0 the brain
/// set, k the k-th region) and the stuffing's count of warped vertices.
struct Body {
    mesh: Mesh,
    surface_nodes: Vec<usize>,
    labels_of: Vec<u8>,
    warped: usize,
}

/// Stuffed tetrahedra (split by region) or hexahedra on the brain's field; refused when no
/// element is left.
fn volume_mesh(
    fields: &Fields,
    params: &MeshParams,
    lo: Point3<f64>,
    hi: Point3<f64>,
    brain_voxels: usize,
    laps: &mut Laps,
) -> Result<Body, MeshgenError> {
    let f = |p: &Point3<f64>| fields.brain.eval(p);
    let body = match params.element {
        ElementType::T4 => {
            let mut s = stuff(&f, lo, hi, params.size, Fill::All);
            laps.lap("stuffing");
            let labels_of = if fields.region_fields.is_empty() {
                vec![0u8; s.tets.len()]
            } else {
                let l = regions::split(&mut s, &fields.region_fields);
                laps.lap("regions");
                l
            };
            let surface_nodes: Vec<usize> =
                (0..s.nodes.len()).filter(|&i| s.on_surface[i]).collect();
            let elements = s.tets.iter().map(|t| Element::tet4(t.map(|v| v as usize))).collect();
            Body { mesh: Mesh::new(s.nodes, elements), surface_nodes, labels_of, warped: s.warped }
        }
        ElementType::H8 => {
            let rf: Vec<_> =
                fields.region_fields.iter().map(|r| move |p: &Point3<f64>| r.eval(p)).collect();
            let g = hex::hex_grid(&f, &rf, lo, hi, params.size);
            let elements = g.hexes.iter().map(|h| Element::hex8(*h)).collect();
            let mesh = Mesh::new(g.nodes, elements);
            let surface_nodes = mesh.boundary().volume_node;
            laps.lap("hexahedra");
            Body { mesh, surface_nodes, labels_of: g.label, warped: 0 }
        }
    };
    if body.mesh.elements.is_empty() {
        return Err(MeshgenError::Check {
            what: "brain mesh",
            message: format!(
                "no element: the brain ({brain_voxels} voxels) is thinner than --size {} mm; give a smaller --size",
                params.size
            ),
        });
    }
    Ok(body)
}

/// The element set names: the brain set, then one per region (upper case).
fn set_names(params: &MeshParams) -> Vec<String> {
    let mut names = vec![BRAIN_SET.to_string()];
    names.extend(params.regions.iter().map(|r| r.name.to_ascii_uppercase()));
    names
}

/// The element sets (empty ones left out) and the FIXED and CRANIOTOMY node sets.
fn name_sets(
    mesh: &mut Mesh,
    names: &[String],
    labels_of: &[u8],
    surface_nodes: &[usize],
    size: f64,
) {
    for (k, name) in names.iter().enumerate() {
        let set: Vec<usize> =
            (0..labels_of.len()).filter(|&e| labels_of[e] as usize == k).collect();
        if !set.is_empty() {
            mesh.element_sets.insert(name.clone(), set);
        }
    }
    let (fixed, craniotomy) = load_sets(mesh, surface_nodes, size);
    mesh.node_sets.insert(FIXED_SET.into(), fixed);
    mesh.node_sets.insert(CRANIOTOMY_SET.into(), craniotomy);
}

/// The skull cavity's field and surface: offset from the brain, or enclosed by the
/// `--cavity` labels.
fn skull_cavity(
    labels: &Volume<u32>,
    params: &MeshParams,
    fields: &Fields,
    lo: Point3<f64>,
    hi: Point3<f64>,
) -> (SampledField, TriSurface) {
    let skull_h = params.skull_size.unwrap_or(params.size);
    let max_spacing = labels.grid.spacing().iter().copied().fold(0.0, f64::max);
    let work = &fields.work;
    // Hexahedra whose centre is inside reach up to half a cell diagonal (√3/2 h) beyond the
    // brain's surface: their cavity is offset from there.
    let offset = match params.element {
        ElementType::T4 => params.skull_offset,
        ElementType::H8 => params.skull_offset + 0.5 * 3f64.sqrt() * params.size,
    };
    let cavity = match &params.cavity_labels {
        None => {
            // The cavity needs no finer field than half its lattice spacing; blocks of at
            // most 2 voxels (3-voxel blocks cost up to 1.5 mm of the gap on MNI152 at 6 mm).
            let coarsen = ((skull_h / (2.0 * max_spacing)).floor() as usize).clamp(1, 2);
            cavity::offset_field(work, &fields.raw_brain, offset, params.closing_radius, coarsen)
        }
        Some(sk) => {
            let skull_ind = work.indicator(labels, |l| sk.contains(&l));
            cavity::enclosed_field(work, &skull_ind, fields.sigma_vox)
        }
    };
    let reach = offset + params.closing_radius + 2.0 * skull_h;
    let (clo, chi) = match &params.cavity_labels {
        None => (lo - Vector3::repeat(reach), hi + Vector3::repeat(reach)),
        Some(_) => world_box(&work.grid),
    };
    let skull = cavity::surface(&cavity, clo, chi, skull_h);
    (cavity, skull)
}

/// The skull must be one closed outward surface without self-intersections.
fn check_skull(skull: &TriSurface) -> Result<(), MeshgenError> {
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
    Ok(())
}

/// Every brain surface node inside the cavity; the smallest gap estimated from the cavity
/// field (mm; NaN for a `--cavity` labelmap, whose indicator is not a distance).
fn brain_inside(
    mesh: &Mesh,
    surface_nodes: &[usize],
    cavity: &SampledField,
    params: &MeshParams,
) -> Result<f64, MeshgenError> {
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
    Ok(match params.cavity_labels {
        // The offset field is a distance (mm); the label indicator is not.
        None => -worst.1,
        Some(_) => f64::NAN,
    })
}

/// The mesh's volume and, per element set, its elements and volume against its labels'.
fn volumes(
    mesh: &Mesh,
    names: &[String],
    labels_of: &[u8],
    counts: &BTreeMap<u32, usize>,
    labels: &Volume<u32>,
    params: &MeshParams,
) -> (f64, Vec<RegionVolume>) {
    let voxel_volume = labels.grid.voxel_volume();
    let vol: Vec<f64> =
        (0..mesh.elements.len()).into_par_iter().map(|e| mesh.element_volume(e)).collect();
    let mesh_volume: f64 = vol.iter().sum();
    let mut regions_out = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let labels_k: Vec<u32> = if k == 0 {
            counts
                .keys()
                .copied()
                .filter(|&l| {
                    in_brain(params, l) && !params.regions.iter().any(|r| r.labels.contains(&l))
                })
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
    (mesh_volume, regions_out)
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
