//! CalculiX, the independent reference: a scene written as a CalculiX deck (the same brain
//! mesh, the same laws per region — Neo-Hookean as NEO HOOKE, St Venant–Kirchhoff as
//! ELASTIC under NLGEOM —, the rigid skull as fixed wedges with penalty contact),
//! CalculiX's printed displacements read back, and the stored reference solutions
//! (`fixtures/<case>/reference/TAG.{json,csv}`) read for comparison. Running ccx is the
//! driver's job (`cargo xtask reference`); the formats live here, side by side.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use bs_mesh::{ElementKind, Point3, TriSurface, Vector3};

use bs_scene::prepare::Prepared;
use bs_scene::scene::MaterialModel;

/// A CalculiX input deck built from a scene.
#[derive(Debug)]
pub struct Deck {
    /// The control file (`job.inp`), which includes the two mesh files.
    pub control: String,
    /// Brain nodes, elements and sets (`brain.inp`).
    pub brain: String,
    /// Skull wedge nodes and elements (`skull.inp`).
    pub skull: String,
}

/// How CalculiX pairs each slave node with a skull face (`*CONTACT PAIR`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Sliding {
    /// The pairs are formed again in every iteration (CalculiX's default).
    #[default]
    Finite,
    /// `SMALL SLIDING`: the pairs are formed at the start of each increment and kept through
    /// its iterations, so a node cannot switch faces between iterations (it still slides
    /// over any distance across increments). A node that alternates between two faces of a
    /// fold of the skull surface otherwise keeps ccx from converging an increment. Within
    /// an increment a node may slide off its face into the next one unresisted, so the
    /// increments are fixed at `increment` of the load (on the MNI152 regions case 5 %
    /// left a node 0.13 mm inside the skull, 1.25 % 0.018 mm).
    Small {
        /// The load fraction of every increment.
        increment: f64,
    },
}

impl Deck {
    /// The deck of a prepared scene with contact of penalty slope `k` (force per length³),
    /// or without the skull when `k` is `None`.
    pub fn new(p: &Prepared, k: Option<f64>) -> Result<Deck, String> {
        Deck::with_sliding(p, k, Sliding::Finite)
    }

    /// [`Deck::new`] with the contact pairing of `sliding`.
    pub fn with_sliding(p: &Prepared, k: Option<f64>, sliding: Sliding) -> Result<Deck, String> {
        if let Some(r) =
            p.scene.regions.iter().find(|r| r.cavity_pressure.is_some_and(|q| q != 0.0))
        {
            return Err(format!(
                "region {}: a cavity pressure is not written into CalculiX decks",
                r.elset
            ));
        }
        if k.is_some() && p.skull.is_none() {
            return Err("the scene has no skull: no contact to compare".into());
        }
        let (tets, hexes) = p.mesh.count_by_kind();
        if hexes > 0 || tets == 0 {
            return Err("CalculiX references are written for tetrahedral meshes (C3D4)".into());
        }
        for (r, region) in p.scene.regions.iter().enumerate() {
            material_card(r, region, 1.0, false)?;
        }
        let composed = bs_scene::compose::compose(p).map_err(|e| e.to_string())?;
        // Stresses in N per length unit squared: Pa × (metres per unit)².
        let stress = p.scene.units.metres().powi(2);
        let mut brain = String::new();
        let nid = |i: usize| p.mesh.node_ids[i];
        brain.push_str("*NODE, NSET=NBRAIN\n");
        for (i, x) in p.mesh.nodes.iter().enumerate() {
            let _ = writeln!(brain, "{}, {:.12e}, {:.12e}, {:.12e}", nid(i), x.x, x.y, x.z);
        }
        // A resected region has no element left: no element set, no section.
        let kept = |r: usize| p.region_of_element.contains(&r);
        for r in (0..p.scene.regions.len()).filter(|&r| kept(r)) {
            let _ = writeln!(brain, "*ELEMENT, TYPE=C3D4, ELSET=REGION{r}");
            for (e, el) in p.mesh.elements.iter().enumerate() {
                if p.region_of_element[e] == r {
                    debug_assert_eq!(el.kind(), ElementKind::Tet4);
                    let n = el.nodes();
                    let _ = writeln!(
                        brain,
                        "{}, {}, {}, {}, {}",
                        p.mesh.element_ids[e],
                        nid(n[0]),
                        nid(n[1]),
                        nid(n[2]),
                        nid(n[3])
                    );
                }
            }
        }
        brain.push_str("*NSET, NSET=SLAVES\n");
        write_ids(&mut brain, composed.slaves.iter().map(|&i| nid(i)));

        // Skull wedges: ids above every brain id.
        let node_base = p.mesh.node_ids.iter().max().copied().unwrap_or(0) + 1;
        let elem_base = p.mesh.element_ids.iter().max().copied().unwrap_or(0) + 1;
        let sk = match &p.skull {
            Some(skull) => skull_wedges(skull, node_base, elem_base)?,
            None => String::new(),
        };

        let mut c = String::new();
        let _ = writeln!(
            c,
            "** brainshift reference deck (cargo xtask reference): CalculiX 2.20.\n\
             ** brain.inp (and skull.inp, with a skull) are written next to it by the same command.\n\
             ** Units: length {}, force N, stress N/{}^2.\n\
             *HEADING\nbrainshift reference, {}",
            p.scene.units.symbol(),
            p.scene.units.symbol(),
            k.map_or("no contact".to_string(), |k| format!("penalty slope K = {k}"))
        );
        c.push_str("*INCLUDE, INPUT=brain.inp\n");
        if !sk.is_empty() {
            c.push_str("*INCLUDE, INPUT=skull.inp\n");
        }
        for (r, region) in p.scene.regions.iter().enumerate().filter(|&(r, _)| kept(r)) {
            let weighed = p.scene.gravity.is_some();
            let _ = writeln!(c, "{}", material_card(r, region, stress, weighed)?);
        }
        // The wedges are fixed: their material only has to make a valid section.
        if !sk.is_empty() {
            c.push_str(
                "*MATERIAL, NAME=RIGID\n*ELASTIC\n1000.0, 0.3\n*SOLID SECTION, ELSET=SKULL, \
                 MATERIAL=RIGID\n",
            );
        }
        if let Some(k) = k {
            let _ = writeln!(
                c,
                "*SURFACE, NAME=SLAVE, TYPE=NODE\nSLAVES\n\
             *SURFACE INTERACTION, NAME=SKULLCONTACT\n\
             *SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n{k:e}, 1.0e-9\n\
             *CONTACT PAIR, INTERACTION=SKULLCONTACT, TYPE=NODE TO SURFACE{}\nSLAVE, MASTER",
                if matches!(sliding, Sliding::Small { .. }) { ", SMALL SLIDING" } else { "" }
            );
        }
        c.push_str("*BOUNDARY\n");
        if !sk.is_empty() {
            c.push_str("NSKULL, 1, 3\n");
        }
        for (i, comps) in p.prescribed.iter().enumerate() {
            for (d, v) in comps.iter().enumerate() {
                if *v == Some(0.0) {
                    let _ = writeln!(c, "{}, {}, {}", nid(i), d + 1, d + 1);
                }
            }
        }
        // Initial, total, minimum and maximum increment of the load.
        let increments = match sliding {
            Sliding::Finite => "0.02, 1.0, 1e-7, 0.05".to_string(),
            Sliding::Small { increment } => format!("{increment}, 1.0, 1e-7, {increment}"),
        };
        let _ = write!(c, "*STEP, NLGEOM, INC=10000\n*STATIC\n{increments}\n*BOUNDARY\n");
        for (i, comps) in p.prescribed.iter().enumerate() {
            for (d, v) in comps.iter().enumerate() {
                if let Some(v) = v.filter(|v| *v != 0.0) {
                    let _ = writeln!(c, "{}, {}, {}, {v:.12e}", nid(i), d + 1, d + 1);
                }
            }
        }
        if let Some(g) = &p.scene.gravity {
            gravity_cards(&mut c, p, g)?;
        }
        c.push_str("*NODE PRINT, NSET=NBRAIN\nU\n*END STEP\n");
        Ok(Deck { control: c, brain, skull: sk })
    }

    /// Writes `job.inp`, `brain.inp` and `skull.inp` (when the scene has a skull) into `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), String> {
        for (name, text) in
            [("job.inp", &self.control), ("brain.inp", &self.brain), ("skull.inp", &self.skull)]
        {
            if text.is_empty() {
                continue; // no skull
            }
            let path = dir.join(name);
            bs_mesh::io::write_atomic(&path, |w| w.write_all(text.as_bytes()))
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    }
}

/// The rigid skull as one layer of C3D6 wedges outside `skull` (`skull.inp`: node set
/// NSKULL, element set SKULL, master surface MASTER), node and element ids from the bases.
fn skull_wedges(skull: &TriSurface, node_base: u64, elem_base: u64) -> Result<String, String> {
    let bbox = skull.bounding_box().ok_or("empty skull")?;
    let thickness = 0.02 * (bbox.1 - bbox.0).norm();
    let nv = skull.vertices.len() as u64;
    let mut sk = String::from("*NODE, NSET=NSKULL\n");
    for (v, x) in skull.vertices.iter().enumerate() {
        let _ = writeln!(sk, "{}, {:.12e}, {:.12e}, {:.12e}", node_base + v as u64, x.x, x.y, x.z);
    }
    // Each wedge is a right prism over its triangle with its own top nodes (offset along
    // the face normal), so no wedge can invert where the skull is concave; the bottom
    // nodes are shared, so the master surface is the skull itself.
    for (t, tri) in skull.triangles.iter().enumerate() {
        let offset = skull.area_normal(t).normalize() * thickness;
        for (j, &v) in tri.iter().enumerate() {
            let y: Point3<f64> = skull.vertices[v] + offset;
            let id = node_base + nv + 3 * t as u64 + j as u64;
            let _ = writeln!(sk, "{id}, {:.12e}, {:.12e}, {:.12e}", y.x, y.y, y.z);
        }
    }
    // Bottom face 1-2-3 = the skull triangle, whose right-hand normal points outward,
    // towards the top face 4-5-6: a positive-volume C3D6 whose face S1 faces the brain.
    sk.push_str("*ELEMENT, TYPE=C3D6, ELSET=SKULL\n");
    for (t, tri) in skull.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|v| node_base + v as u64);
        let top = node_base + nv + 3 * t as u64;
        let _ = writeln!(
            sk,
            "{}, {a}, {b}, {c}, {}, {}, {}",
            elem_base + t as u64,
            top,
            top + 1,
            top + 2
        );
    }
    sk.push_str("*SURFACE, NAME=MASTER\n");
    for t in 0..skull.triangles.len() {
        let _ = writeln!(sk, "{}, S1", elem_base + t as u64);
    }
    Ok(sk)
}

/// The `*MATERIAL` and `*SOLID SECTION` cards of region `r` (`REGION{r}`), stresses scaled
/// by `stress` (N per length unit squared per Pa):
/// * `neo-hookean` → `*HYPERELASTIC, NEO HOOKE` with `C10 = μ/2`, `D1 = 2/κ` (the same
///   decoupled energy as bs-material's law);
/// * `svk` → `*ELASTIC` with `E = 9κμ/(3κ + μ)`, `ν = (3κ − 2μ)/(2(3κ + μ))`: under the
///   deck's `NLGEOM` step CalculiX's linear elastic material relates the second
///   Piola–Kirchhoff stress to the Green–Lagrange strain, i.e. St Venant–Kirchhoff (checked on
///   one confined C3D8 with ccx 2.20: σ₃₃ = (λ + 2μ) λ₃(λ₃² − 1)/2 to its 7 printed digits);
/// * anything else (`ogden`) is refused, naming the region and the models that can be written.
fn material_card(
    r: usize,
    region: &bs_scene::scene::Region,
    stress: f64,
    weighed: bool,
) -> Result<String, String> {
    let m = region.material.moduli()?;
    let (mu, kappa) = (m.mu * stress, m.kappa * stress);
    let law = match region.material.model {
        MaterialModel::NeoHookean => {
            format!("*HYPERELASTIC, NEO HOOKE\n{:.12e}, {:.12e}", mu / 2.0, 2.0 / kappa)
        }
        MaterialModel::Svk => {
            let young = 9.0 * kappa * mu / (3.0 * kappa + mu);
            let poisson = (3.0 * kappa - 2.0 * mu) / (2.0 * (3.0 * kappa + mu));
            format!("*ELASTIC\n{young:.12e}, {poisson:.12e}")
        }
        MaterialModel::Ogden => {
            return Err(format!(
                "[[region]] #{} (elset '{}'): model = \"ogden\" has no CalculiX counterpart \
                 written here; a reference deck can hold \"neo-hookean\" (NEO HOOKE) and \
                 \"svk\" (ELASTIC under NLGEOM) regions",
                r + 1,
                region.elset
            ));
        }
    };
    // The density as given (kg/m³): with `*DLOAD GRAV` only the product ρ g enters a
    // static step, and `gravity_cards` scales g to make it N per length unit cubed.
    let density = match region.material.density {
        Some(d) if weighed => format!("\n*DENSITY\n{d:.12e}"),
        _ => String::new(),
    };
    Ok(format!(
        "*MATERIAL, NAME=M{r}\n{law}{density}\n*SOLID SECTION, ELSET=REGION{r}, MATERIAL=M{r}"
    ))
}

/// The `*DLOAD` cards of the scene's gravity, ramped with the step: `GRAV` of magnitude
/// `a × (metres per unit)³` (so that the card's density in kg/m³ times it is the weight in
/// N per length unit cubed) on each region's set; with a fluid, one card per element whose
/// magnitude carries the buoyancy, `a (ρ − φ ρ_f)/ρ` with `φ` the element's submerged volume
/// fraction (exact for elements wholly above or below the level; an element the level cuts
/// gets its share spread as its own weight is, where brainshift integrates the cut exactly).
fn gravity_cards(c: &mut String, p: &Prepared, g: &bs_scene::scene::Gravity) -> Result<(), String> {
    let unit = g.unit().ok_or("[gravity] direction is zero")?;
    let scale = g.acceleration * p.scene.units.metres().powi(3);
    let [nx, ny, nz] = unit;
    c.push_str("*DLOAD\n");
    let Some(f) = &g.fluid else {
        for r in (0..p.scene.regions.len()).filter(|r| p.region_of_element.contains(r)) {
            let _ = writeln!(c, "REGION{r}, GRAV, {scale:.12e}, {nx:.12e}, {ny:.12e}, {nz:.12e}");
        }
        return Ok(());
    };
    let level = Point3::from(f.level);
    let down = Vector3::from(unit);
    for (e, el) in p.mesh.elements.iter().enumerate() {
        let rho = p.scene.regions[p.region_of_element[e]].material.density_or_default();
        let n = el.nodes();
        let h: [f64; 4] = std::array::from_fn(|a| down.dot(&(p.mesh.nodes[n[a]] - level)));
        let wet: f64 = bs_dr::body::submerged_tet(h).iter().sum();
        let m = scale * (rho - wet * f.density) / rho;
        let _ = writeln!(
            c,
            "{}, GRAV, {m:.12e}, {nx:.12e}, {ny:.12e}, {nz:.12e}",
            p.mesh.element_ids[e]
        );
    }
    Ok(())
}

fn write_ids(out: &mut String, ids: impl Iterator<Item = u64>) {
    let ids: Vec<u64> = ids.collect();
    for chunk in ids.chunks(12) {
        let line: Vec<String> = chunk.iter().map(u64::to_string).collect();
        let _ = writeln!(out, "{},", line.join(", "));
    }
}

/// One printed increment: its step time and the displacements by node id.
pub type DatBlock = (f64, Vec<(u64, [f64; 3])>);

/// Parses the last `displacements (vx,vy,vz)` block of a .dat file.
pub fn parse_dat(text: &str) -> Option<DatBlock> {
    let mut last: Option<DatBlock> = None;
    let mut current: Option<DatBlock> = None;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("displacements (vx,vy,vz)") {
            if let Some(c) = current.take() {
                last = Some(c);
            }
            let time = t.rsplit("time").next().and_then(|s| s.trim().parse::<f64>().ok());
            current = Some((time.unwrap_or(f64::NAN), Vec::new()));
            continue;
        }
        let Some((_, rows)) = current.as_mut() else { continue };
        let f: Vec<&str> = t.split_whitespace().collect();
        if f.len() == 4
            && let (Ok(id), Ok(x), Ok(y), Ok(z)) =
                (f[0].parse::<u64>(), f[1].parse(), f[2].parse(), f[3].parse())
        {
            rows.push((id, [x, y, z]));
            continue;
        }
        if !t.is_empty() && !rows.is_empty() {
            // Another block starts: close this one.
            last = current.take();
        }
    }
    current.or(last)
}

/// A stored CalculiX result: displacements by node id and its metadata.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Displacements by node id.
    pub displacements: HashMap<u64, Vector3<f64>>,
    /// Its metadata (ccx version, contact slope, wall time, outcome).
    pub meta: serde_json::Value,
}

/// Reads `TAG.json` and `TAG.csv` of a reference folder; `None` when the case has none.
/// A run that stopped short has no `TAG.csv`; its last converged increment, if stored, is
/// the file its metadata names as `partial` ([`read_partial`]).
pub fn read_reference(dir: &Path, tag: &str) -> Result<Option<Reference>, String> {
    let meta_path = dir.join(format!("{tag}.json"));
    let Ok(meta_text) = std::fs::read_to_string(&meta_path) else { return Ok(None) };
    let meta: serde_json::Value =
        serde_json::from_str(&meta_text).map_err(|e| format!("{}: {e}", meta_path.display()))?;
    let csv_path = dir.join(format!("{tag}.csv"));
    let displacements =
        if csv_path.exists() { read_displacements(&csv_path)? } else { HashMap::new() };
    Ok(Some(Reference { displacements, meta }))
}

/// The last converged increment of a stored run that stopped short (its metadata's
/// `partial` file, at `load_fraction_reached` of the load), with the run's metadata; `None`
/// when it has none.
pub fn read_partial(dir: &Path, r: &Reference) -> Result<Option<Reference>, String> {
    let Some(name) = r.meta["partial"].as_str() else { return Ok(None) };
    let displacements = read_displacements(&dir.join(name))?;
    Ok(Some(Reference { displacements, meta: r.meta.clone() }))
}

/// `node_id,ux,uy,uz` rows after a header line.
fn read_displacements(csv_path: &Path) -> Result<HashMap<u64, Vector3<f64>>, String> {
    let text =
        std::fs::read_to_string(csv_path).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let mut displacements = HashMap::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let bad = || format!("{}:{}: expected node_id,ux,uy,uz", csv_path.display(), n + 1);
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 4 {
            return Err(bad());
        }
        let id: u64 = f[0].parse().map_err(|_| bad())?;
        let v: Vec<f64> =
            f[1..].iter().map(|s| s.parse::<f64>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        displacements.insert(id, Vector3::new(v[0], v[1], v[2]));
    }
    Ok(displacements)
}

/// The reference field in mesh node order.
pub fn field(p: &Prepared, r: &Reference, what: &str) -> Result<Vec<Vector3<f64>>, String> {
    p.mesh
        .node_ids
        .iter()
        .map(|id| {
            r.displacements
                .get(id)
                .copied()
                .ok_or_else(|| format!("{what}: node {id} has no reference displacement"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regions_fixture() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152-regions/scene.toml")
    }

    /// Small sliding: the contact pair says so and every increment is the fixed share of
    /// the load; the default deck keeps CalculiX's pairing and automatic increments.
    #[test]
    fn small_sliding_fixes_the_pairs_and_the_increments() {
        let p = Prepared::load(&regions_fixture()).unwrap();
        let small = Deck::with_sliding(&p, Some(1.0), Sliding::Small { increment: 0.0125 });
        let c = small.unwrap().control;
        assert!(c.contains("TYPE=NODE TO SURFACE, SMALL SLIDING\nSLAVE, MASTER\n"), "{c}");
        assert!(c.contains("*STATIC\n0.0125, 1.0, 1e-7, 0.0125\n"), "{c}");
        let c = Deck::new(&p, Some(1.0)).unwrap().control;
        assert!(c.contains("TYPE=NODE TO SURFACE\nSLAVE, MASTER\n"), "{c}");
        assert!(c.contains("*STATIC\n0.02, 1.0, 1e-7, 0.05\n"), "{c}");
    }

    /// The regions fixture's deck: NEO HOOKE for the parenchyma and the tumour (C10 = μ/2,
    /// D1 = 2/κ in MPa), ELASTIC for the St Venant–Kirchhoff ventricles (E = 100 Pa,
    /// ν = 0.1 back from μ and κ), each on its own element set, in an NLGEOM step.
    #[test]
    fn writes_neo_hookean_and_svk_regions() {
        let p = Prepared::load(&regions_fixture()).unwrap();
        let deck = Deck::new(&p, Some(10.0)).unwrap();
        let names: Vec<&str> = p.scene.regions.iter().map(|r| r.elset.as_str()).collect();
        assert_eq!(names, ["BRAIN", "TUMOUR", "VENTRICLES"]);
        let c = &deck.control;
        let card = |r: usize| {
            let start = c.find(&format!("*MATERIAL, NAME=M{r}\n")).unwrap();
            let end = start + c[start..].find("*SOLID SECTION").unwrap();
            let section = &c[end..end + c[end..].find('\n').unwrap()];
            assert_eq!(section, format!("*SOLID SECTION, ELSET=REGION{r}, MATERIAL=M{r}"));
            let lines: Vec<&str> = c[start..end].lines().collect();
            let values: Vec<f64> = lines[2].split(',').map(|v| v.trim().parse().unwrap()).collect();
            (lines[1].to_string(), values)
        };
        // E = 3000 Pa, ν = 0.49: μ = 1006.71 Pa, κ = 50 000 Pa; ×1e-6 to N/mm².
        let (law, v) = card(0);
        assert_eq!(law, "*HYPERELASTIC, NEO HOOKE");
        let (mu, kappa) = (3000.0 / 2.98 * 1e-6, 3000.0 / (3.0 * 0.02) * 1e-6);
        assert!((v[0] - mu / 2.0).abs() <= 1e-12 * mu && (v[1] - 2.0 / kappa).abs() <= 1e-6);
        let (law, v) = card(1);
        assert_eq!(law, "*HYPERELASTIC, NEO HOOKE");
        assert!((v[0] - 3.0 * mu / 2.0).abs() <= 1e-12 * mu);
        let (law, v) = card(2);
        assert_eq!(law, "*ELASTIC");
        assert!((v[0] - 100e-6).abs() <= 1e-15 && (v[1] - 0.1).abs() <= 1e-12, "{v:?}");
        assert!(c.contains("*STEP, NLGEOM"));
        // Each region's elements are its element set.
        for (r, name) in names.iter().enumerate() {
            let n = p.region_of_element.iter().filter(|&&x| x == r).count();
            let set = p.mesh.element_set(name).unwrap().len();
            assert_eq!(n, set, "{name}");
            assert!(deck.brain.contains(&format!("*ELEMENT, TYPE=C3D4, ELSET=REGION{r}\n")));
        }
    }

    /// A law CalculiX is not given here is refused before anything is written, naming the
    /// region and what can be written.
    #[test]
    fn refuses_an_ogden_region() {
        let path = regions_fixture();
        let mut scene = bs_scene::Scene::load(&path).unwrap();
        scene.regions[2].material.model = MaterialModel::Ogden;
        scene.regions[2].material.alpha = Some(-4.7);
        let p = Prepared::from_scene(&path, scene).unwrap();
        let err = Deck::new(&p, Some(10.0)).unwrap_err();
        assert!(err.contains("[[region]] #3 (elset 'VENTRICLES'): model = \"ogden\""), "{err}");
        assert!(err.contains("\"svk\" (ELASTIC under NLGEOM)"), "{err}");
    }

    /// Two printed increments: the parser keeps the last one, with its step time.
    #[test]
    fn parses_the_last_displacement_block() {
        let dat = "
 displacements (vx,vy,vz) for set NBRAIN and time  0.5000000E+00

         1  1.000000E-01  0.000000E+00 -2.000000E-01
         2  0.000000E+00  3.000000E-01  0.000000E+00

 displacements (vx,vy,vz) for set NBRAIN and time  0.1000000E+01

         1  2.000000E-01  0.000000E+00 -4.000000E-01
         2 -1.000000E-03  6.000000E-01  5.000000E-02
";
        let (time, rows) = parse_dat(dat).unwrap();
        assert_eq!(time, 1.0);
        assert_eq!(rows, vec![(1, [0.2, 0.0, -0.4]), (2, [-1e-3, 0.6, 0.05])]);
    }
}
