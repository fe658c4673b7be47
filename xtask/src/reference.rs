//! `cargo xtask reference`: independent reference solutions of the contact fixtures with
//! CalculiX (ccx 2.20, Debian package `calculix-ccx`).
//!
//! For each case the scene is read with the same code as `brainshift run`, and a CalculiX
//! deck is written with:
//! * the same brain mesh as C3D4 elements (so it is compared with our T4 element),
//! * `*HYPERELASTIC, NEO HOOKE` with C10 = μ/2 and D1 = 2/κ (the decoupled Neo-Hookean law of
//!   bs-material; stresses in N/(length unit)², e.g. MPa for mm),
//! * the rigid skull as one layer of C3D6 wedges (right prisms) extruded outward from the
//!   skull triangles, every wedge node fixed; the wedges' inner faces (S1) are the master surface,
//! * frictionless node-to-surface penalty contact with the run's slave nodes as the slave
//!   surface and a linear pressure–overclosure law of slope K,
//! * the scene's fixed and prescribed displacements in one `NLGEOM` static step.
//!
//! ccx runs under a memory cap (`ulimit -v`) and a time limit; its displacements (from
//! `*NODE PRINT` in the .dat file) are stored with the control deck, the ccx version, the
//! wall time and K in `fixtures/<case>/reference/`. Two slopes (K = 1 and 10 per length unit,
//! MPa/mm for mm scenes) are run: their difference is the reference's own uncertainty.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use bs_mesh::{ElementKind, Point3, Vector3};
use bs_scene::Prepared;
use bs_scene::scene::MaterialModel;

/// A reference case: a fixture folder, its scene and the slopes to run.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    /// Fixture folder name under `fixtures/`.
    pub name: &'static str,
    /// Scene file in that folder.
    pub scene: &'static str,
    /// Output stem under `reference/` (`ccx` → `ccx-k10.csv`).
    pub stem: &'static str,
    /// Penalty slopes to run (one run without contact when `contact` is false).
    pub slopes: &'static [f64],
    /// Whether the skull is in the deck. Without it the comparison isolates material,
    /// element and geometric nonlinearity from the contact formulation.
    pub contact: bool,
}

/// The stored references: every contact fixture at a load ccx converges at, and the paper's
/// 40 mm ellipsoid load, whose ccx outcome (it may fail) is recorded for the stability map.
pub const CASES: &[Case] = &[
    Case {
        name: "sphere-shell",
        scene: "scene.toml",
        stem: "ccx",
        slopes: &[1.0, 10.0],
        contact: true,
    },
    Case {
        name: "ellipsoid",
        scene: "scene.toml",
        stem: "ccx",
        slopes: &[1.0, 10.0],
        contact: true,
    },
    Case {
        name: "ellipsoid",
        scene: "scene.toml",
        stem: "ccx-nocontact",
        slopes: &[0.0],
        contact: false,
    },
    Case { name: "mni152", scene: "scene.toml", stem: "ccx", slopes: &[1.0, 10.0], contact: true },
    Case {
        name: "ellipsoid",
        scene: "scene-40mm.toml",
        stem: "ccx-40mm",
        slopes: &[10.0],
        contact: true,
    },
];

/// Options of `cargo xtask reference`.
#[derive(Debug, Clone)]
pub struct Options {
    /// Only cases whose `name` or `name/stem` matches.
    pub only: Option<String>,
    /// Write the decks but do not run ccx.
    pub deck_only: bool,
    /// Time limit per ccx run, seconds.
    pub timeout: u64,
    /// Memory cap per ccx run, GiB.
    pub memory_gib: u64,
    /// ccx threads.
    pub threads: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options { only: None, deck_only: false, timeout: 3600, memory_gib: 8, threads: 1 }
    }
}

/// Parses `cargo xtask reference` arguments.
pub fn parse_args(args: &[String]) -> Result<Options, String> {
    let mut o = Options::default();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value =
            |name: &str| it.next().cloned().ok_or_else(|| format!("{name} needs a value"));
        match a.as_str() {
            "--case" => o.only = Some(value("--case")?),
            "--deck-only" => o.deck_only = true,
            "--timeout" => {
                o.timeout = value("--timeout")?.parse().map_err(|e| format!("--timeout: {e}"))?;
            }
            "--memory-gib" => {
                o.memory_gib =
                    value("--memory-gib")?.parse().map_err(|e| format!("--memory-gib: {e}"))?;
            }
            "--threads" => {
                o.threads = value("--threads")?.parse().map_err(|e| format!("--threads: {e}"))?;
            }
            other => return Err(format!("unknown option '{other}'")),
        }
    }
    Ok(o)
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs the selected cases.
pub fn run(o: &Options) -> Result<(), String> {
    let version = if o.deck_only { None } else { Some(ccx_version()?) };
    let root = workspace_root();
    let mut selected = 0;
    for case in CASES {
        let label = format!("{}/{}", case.name, case.stem);
        if o.only.as_ref().is_some_and(|only| only != case.name && *only != label) {
            continue;
        }
        selected += 1;
        let prepared = Prepared::load(&root.join("fixtures").join(case.name).join(case.scene))
            .map_err(|e| e.to_string())?;
        for &k in case.slopes {
            let tag =
                if case.contact { format!("{}-k{}", case.stem, k) } else { case.stem.to_string() };
            let what = if case.contact { format!("K={k}") } else { "no contact".into() };
            let work = root.join("target/reference").join(case.name).join(&tag);
            std::fs::create_dir_all(&work).map_err(|e| format!("{}: {e}", work.display()))?;
            let deck = Deck::new(&prepared, case.contact.then_some(k))?;
            deck.write(&work)?;
            let store = root.join("fixtures").join(case.name).join("reference");
            std::fs::create_dir_all(&store).map_err(|e| format!("{}: {e}", store.display()))?;
            std::fs::copy(work.join("job.inp"), store.join(format!("{tag}.inp")))
                .map_err(|e| format!("copying the deck: {e}"))?;
            let Some(version) = &version else {
                println!("{label} {what}: deck written to {}", work.display());
                continue;
            };
            println!("{label} {what}: running ccx in {} ...", work.display());
            let outcome = run_ccx(&work, o)?;
            let result = collect(&prepared, &deck, &work, &outcome);
            println!(
                "{label} {what}: {} in {:.1} s, load reached {:.3}{}",
                if result.converged { "converged" } else { "FAILED" },
                outcome.wall_seconds,
                result.load_fraction,
                result.message.as_deref().map(|m| format!(" ({m})")).unwrap_or_default()
            );
            result.store(&store, &tag, version, case.contact.then_some(k), &outcome, &prepared)?;
        }
    }
    if selected == 0 {
        let names: Vec<String> = CASES.iter().map(|c| format!("{}/{}", c.name, c.stem)).collect();
        return Err(format!("no case matches; cases: {}", names.join(", ")));
    }
    Ok(())
}

fn ccx_version() -> Result<String, String> {
    let out = Command::new("ccx").arg("-v").output().map_err(|_| {
        "CalculiX (ccx) is not on PATH. Install it with `apt-get install calculix-ccx` \
         (Debian package, version 2.20), or pass --deck-only to write the decks only. \
         `cargo xtask validate` does not need it: it uses the stored references."
            .to_string()
    })?;
    let text = String::from_utf8_lossy(&out.stdout);
    let version = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("This is Version "))
        .map(|v| v.trim().to_string())
        .unwrap_or_else(|| "unknown".into());
    Ok(version)
}

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

impl Deck {
    /// The deck of a prepared scene with contact of penalty slope `k` (force per length³),
    /// or without the skull when `k` is `None`.
    pub fn new(p: &Prepared, k: Option<f64>) -> Result<Deck, String> {
        let skull = p.skull.as_ref().ok_or("the scene has no skull: nothing to compare")?;
        let (tets, hexes) = p.mesh.count_by_kind();
        if hexes > 0 || tets == 0 {
            return Err("CalculiX references are written for tetrahedral meshes (C3D4)".into());
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
        for (r, region) in p.scene.regions.iter().enumerate() {
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
            if region.material.model != MaterialModel::NeoHookean {
                return Err(format!(
                    "region '{}': only Neo-Hookean regions have a CalculiX counterpart here",
                    region.elset
                ));
            }
        }
        brain.push_str("*NSET, NSET=SLAVES\n");
        write_ids(&mut brain, composed.slaves.iter().map(|&i| nid(i)));

        // Skull wedges: ids above every brain id.
        let node_base = p.mesh.node_ids.iter().max().copied().unwrap_or(0) + 1;
        let elem_base = p.mesh.element_ids.iter().max().copied().unwrap_or(0) + 1;
        let bbox = skull.bounding_box().ok_or("empty skull")?;
        let thickness = 0.02 * (bbox.1 - bbox.0).norm();
        let nv = skull.vertices.len() as u64;
        let mut sk = String::from("*NODE, NSET=NSKULL\n");
        for (v, x) in skull.vertices.iter().enumerate() {
            let _ =
                writeln!(sk, "{}, {:.12e}, {:.12e}, {:.12e}", node_base + v as u64, x.x, x.y, x.z);
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

        let mut c = String::new();
        let _ = writeln!(
            c,
            "** brainshift reference deck (cargo xtask reference): CalculiX 2.20.\n\
             ** brain.inp and skull.inp are written next to it by the same command.\n\
             ** Units: length {}, force N, stress N/{}^2.\n\
             *HEADING\nbrainshift reference, {}",
            p.scene.units.symbol(),
            p.scene.units.symbol(),
            k.map_or("no contact".to_string(), |k| format!("penalty slope K = {k}"))
        );
        c.push_str("*INCLUDE, INPUT=brain.inp\n*INCLUDE, INPUT=skull.inp\n");
        for (r, region) in p.scene.regions.iter().enumerate() {
            let m = region.material.moduli()?;
            let (mu, kappa) = (m.mu * stress, m.kappa * stress);
            let _ = writeln!(
                c,
                "*MATERIAL, NAME=M{r}\n*HYPERELASTIC, NEO HOOKE\n{:.12e}, {:.12e}\n\
                 *SOLID SECTION, ELSET=REGION{r}, MATERIAL=M{r}",
                mu / 2.0,
                2.0 / kappa
            );
        }
        // The wedges are fixed: their material only has to make a valid section.
        c.push_str(
            "*MATERIAL, NAME=RIGID\n*ELASTIC\n1000.0, 0.3\n*SOLID SECTION, ELSET=SKULL, \
             MATERIAL=RIGID\n",
        );
        if let Some(k) = k {
            let _ = writeln!(
                c,
                "*SURFACE, NAME=SLAVE, TYPE=NODE\nSLAVES\n\
             *SURFACE INTERACTION, NAME=SKULLCONTACT\n\
             *SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n{k:e}, 1.0e-9\n\
             *CONTACT PAIR, INTERACTION=SKULLCONTACT, TYPE=NODE TO SURFACE\nSLAVE, MASTER"
            );
        }
        c.push_str("*BOUNDARY\nNSKULL, 1, 3\n");
        for (i, comps) in p.prescribed.iter().enumerate() {
            for (d, v) in comps.iter().enumerate() {
                if *v == Some(0.0) {
                    let _ = writeln!(c, "{}, {}, {}", nid(i), d + 1, d + 1);
                }
            }
        }
        c.push_str("*STEP, NLGEOM, INC=10000\n*STATIC\n0.02, 1.0, 1e-7, 0.05\n*BOUNDARY\n");
        for (i, comps) in p.prescribed.iter().enumerate() {
            for (d, v) in comps.iter().enumerate() {
                if let Some(v) = v.filter(|v| *v != 0.0) {
                    let _ = writeln!(c, "{}, {}, {}, {v:.12e}", nid(i), d + 1, d + 1);
                }
            }
        }
        c.push_str("*NODE PRINT, NSET=NBRAIN\nU\n*END STEP\n");
        Ok(Deck { control: c, brain, skull: sk })
    }

    /// Writes `job.inp`, `brain.inp` and `skull.inp` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), String> {
        for (name, text) in
            [("job.inp", &self.control), ("brain.inp", &self.brain), ("skull.inp", &self.skull)]
        {
            let path = dir.join(name);
            std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        }
        Ok(())
    }
}

fn write_ids(out: &mut String, ids: impl Iterator<Item = u64>) {
    let ids: Vec<u64> = ids.collect();
    for chunk in ids.chunks(12) {
        let line: Vec<String> = chunk.iter().map(u64::to_string).collect();
        let _ = writeln!(out, "{},", line.join(", "));
    }
}

/// How a ccx process ended.
#[derive(Debug)]
pub struct CcxOutcome {
    /// Exit status (None: killed by a signal).
    pub status: Option<i32>,
    /// Whether the time limit stopped it.
    pub timed_out: bool,
    /// Wall time.
    pub wall_seconds: f64,
    /// The tail of its output.
    pub log_tail: String,
}

fn run_ccx(work: &Path, o: &Options) -> Result<CcxOutcome, String> {
    let kib = o.memory_gib * 1024 * 1024;
    let script = format!("ulimit -v {kib}; exec timeout {} ccx -i job > ccx.log 2>&1", o.timeout);
    let started = Instant::now();
    let status = Command::new("sh")
        .arg("-c")
        .arg(script)
        .current_dir(work)
        .env("OMP_NUM_THREADS", o.threads.to_string())
        .env("CCX_NPROC_EQUATION_SOLVER", o.threads.to_string())
        .status()
        .map_err(|e| format!("cannot start ccx: {e}"))?;
    let wall_seconds = started.elapsed().as_secs_f64();
    let log = std::fs::read_to_string(work.join("ccx.log")).unwrap_or_default();
    let tail: Vec<&str> = log.lines().rev().take(15).collect();
    Ok(CcxOutcome {
        status: status.code(),
        timed_out: status.code() == Some(124),
        wall_seconds,
        log_tail: tail.into_iter().rev().collect::<Vec<_>>().join("\n"),
    })
}

/// Displacements and status read back from a ccx run.
#[derive(Debug)]
pub struct Collected {
    /// Whether the full load was reached.
    pub converged: bool,
    /// Step time of the last printed increment (1 = full load).
    pub load_fraction: f64,
    /// Displacements of the last printed increment, by node id.
    pub displacements: Vec<(u64, [f64; 3])>,
    /// Why it failed, if it did.
    pub message: Option<String>,
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

fn collect(p: &Prepared, _deck: &Deck, work: &Path, outcome: &CcxOutcome) -> Collected {
    let dat = std::fs::read_to_string(work.join("job.dat")).unwrap_or_default();
    let parsed = parse_dat(&dat);
    let (load_fraction, displacements) = parsed.unwrap_or((0.0, Vec::new()));
    let complete = displacements.len() == p.mesh.nodes.len();
    let finished = outcome.log_tail.contains("Job finished");
    let converged = finished && complete && (load_fraction - 1.0).abs() < 1e-9;
    let message = if converged {
        None
    } else if outcome.timed_out {
        Some(format!("stopped by the time limit after {:.0} s", outcome.wall_seconds))
    } else {
        let last = outcome
            .log_tail
            .lines()
            .rev()
            .find(|l| {
                l.contains("ERROR") || l.contains("*ERROR") || l.contains("increment size smaller")
            })
            .unwrap_or("no 'Job finished' in the ccx log")
            .trim()
            .to_string();
        Some(format!("exit status {:?}: {last}", outcome.status))
    };
    Collected { converged, load_fraction, displacements, message }
}

impl Collected {
    fn store(
        &self,
        dir: &Path,
        tag: &str,
        version: &str,
        k: Option<f64>,
        outcome: &CcxOutcome,
        p: &Prepared,
    ) -> Result<(), String> {
        let mut max_penetration = None;
        if self.converged {
            let mut csv = String::from("node_id,ux,uy,uz\n");
            for (id, u) in &self.displacements {
                let _ = writeln!(csv, "{id},{:e},{:e},{:e}", u[0], u[1], u[2]);
            }
            let path = dir.join(format!("{tag}.csv"));
            std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;
            if k.is_some() {
                max_penetration = Some(penetration(p, &self.displacements)?);
            }
        }
        let json = serde_json::json!({
            "ccx_version": version,
            "penalty_slope": k,
            "penalty_slope_units": format!("N/{}^3", p.scene.units.symbol()),
            "element": "C3D4",
            "converged": self.converged,
            "load_fraction_reached": self.load_fraction,
            "wall_seconds": outcome.wall_seconds,
            "max_penetration": max_penetration,
            "message": self.message,
            "command": "cargo xtask reference",
        });
        let path = dir.join(format!("{tag}.json"));
        let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
        std::fs::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// Largest distance of a slave node outside the skull in a displacement field given by id.
fn penetration(p: &Prepared, u: &[(u64, [f64; 3])]) -> Result<f64, String> {
    let c = bs_scene::compose::compose(p).map_err(|e| e.to_string())?;
    let mut field = vec![Vector3::zeros(); p.mesh.nodes.len()];
    for (id, d) in u {
        let i = p.mesh.node_index(*id).ok_or_else(|| format!("ccx printed unknown node {id}"))?;
        field[i] = Vector3::new(d[0], d[1], d[2]);
    }
    Ok(bs_scene::verify::contact_state(p, &c, &field, 0.0).max_penetration)
}

#[cfg(test)]
mod tests {
    use super::*;

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
