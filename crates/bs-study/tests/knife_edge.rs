//! The knife-edge test: the stability map's Newton–Krylov block cells
//! (forcing, indentation depths, Poisson's ratio for T4 and T4ANP up to 0.4999) run three
//! ways — as they are, with the material constants changed in the last digits, and with the
//! mesh's node order permuted — must end with the same verdict after Newton iteration counts
//! within a factor [`COUNT_RATIO`]. Neither change alters the problem: a displacement-driven
//! problem without body forces has the same solution for any uniform scaling of the moduli,
//! and a renumbering of the nodes is the same mesh. Only rounding differs, so a solver whose
//! verdict flips decides its runs on a knife edge (the old solver did:
//! T4ANP at ν = 0.4999 flipped between `ElementInverted` and converged when κ changed by
//! 1e-12 relative).

use std::path::PathBuf;

use bs_mesh::Mesh;
use bs_mesh::io::Fields;
use bs_mesh::rng::SplitMix64;
use bs_scene::Prepared;
use bs_scene::scene::SolverKind;
use bs_study::study::Variant;
use bs_study::verdict::{Verdict, classify};

use bs_study::stability::measure::{Measured, measure};
use bs_study::stability::{Spec, as_built, newton_krylov_block_specs};
use bs_study::util::root;

/// Relative change of the material constants.
const EPS: f64 = 1e-12;

/// The mesh with its nodes in a fixed pseudo-random order (Fisher–Yates with SplitMix64,
/// seed 23): coordinates moved, elements and node sets renumbered, ids 1…n in the new order.
fn permute_nodes(mesh: Mesh) -> Mesh {
    let n = mesh.nodes.len();
    let mut old_of: Vec<usize> = (0..n).collect();
    let mut rng = SplitMix64::new(23);
    for i in (1..n).rev() {
        old_of.swap(i, rng.below(i + 1));
    }
    let mut new_of = vec![0; n];
    for (new, &old) in old_of.iter().enumerate() {
        new_of[old] = new;
    }
    let elements = mesh
        .elements
        .iter()
        .map(|e| {
            let mut e = *e;
            e.nodes_mut().iter_mut().for_each(|k| *k = new_of[*k]);
            e
        })
        .collect();
    let mut m = Mesh::new(old_of.iter().map(|&o| mesh.nodes[o]).collect(), elements);
    m.element_ids = mesh.element_ids;
    m.element_sets = mesh.element_sets;
    m.node_sets = mesh
        .node_sets
        .into_iter()
        .map(|(name, set)| {
            let mut set: Vec<usize> = set.into_iter().map(|i| new_of[i]).collect();
            set.sort_unstable();
            (name, set)
        })
        .collect();
    m
}

/// The scene with every region's law given by (μ, κ) instead of (E, ν), from
/// E·(1 + 1e-12) and with κ·(1 + 1e-12) on top: both moduli change in the last digits, and
/// κ/μ with them.
fn perturb_material(mut q: Prepared) -> Result<Prepared, String> {
    for r in &mut q.scene.regions {
        let m = &mut r.material;
        let (Some(e), Some(nu)) = (m.youngs_modulus, m.poisson_ratio) else {
            return Err(format!("region '{}' is not given by (E, ν)", r.elset));
        };
        let e = e * (1.0 + EPS);
        m.shear_modulus = Some(e / (2.0 * (1.0 + nu)));
        m.bulk_modulus = Some(e / (3.0 * (1.0 - 2.0 * nu)) * (1.0 + EPS));
        m.youngs_modulus = None;
        m.poisson_ratio = None;
    }
    Ok(q)
}

/// The cell solved with its material perturbed: the variant applied first (it sets ν), then
/// the law rebuilt from the perturbed (μ, κ), then solved without the changes already made.
fn perturbed(spec: &Spec) -> Measured {
    let scene = spec.scene.as_ref().expect("the block scenes load");
    let q = spec.variant.apply(scene).expect("the variant applies");
    let q = perturb_material(q).expect("(E, ν) regions");
    let v = Variant { poisson_ratio: None, load_factor: None, ..spec.variant.clone() };
    measure(&v, &q)
}

/// Verdict and Newton iterations of a run.
fn signature(m: &Measured) -> (String, usize) {
    (Verdict::text(&classify(&m.result, 1e-3)), m.metrics().steps)
}

/// The smallest and largest Newton iteration count of a cell's runs.
fn count_range(ways: &[(String, usize)]) -> (usize, usize) {
    ways.iter().fold((usize::MAX, 0), |(lo, hi), w| (lo.min(w.1), hi.max(w.1)))
}

fn dir(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("brainshift-knife-edge-{}-{name}", std::process::id()))
}

/// The permutation is one (every node once), moves most nodes, and leaves the mesh the same
/// mesh: the same element volumes in the same order, the same coordinates in every set.
#[test]
fn permuted_block_is_the_same_mesh() {
    let m = bs_study::stability::block(4, 2.0, true);
    let p = permute_nodes(m.clone());
    let moved = (0..m.nodes.len()).filter(|&i| m.nodes[i] != p.nodes[i]).count();
    assert!(moved > m.nodes.len() * 9 / 10, "{moved} of {}", m.nodes.len());
    for e in 0..m.elements.len() {
        assert_eq!(m.element_volume(e), p.element_volume(e), "element {e}");
    }
    for (name, set) in &m.node_sets {
        let mut a: Vec<_> = set.iter().map(|&i| m.nodes[i].coords.as_slice().to_vec()).collect();
        let mut b: Vec<_> =
            p.node_sets[name].iter().map(|&i| p.nodes[i].coords.as_slice().to_vec()).collect();
        a.sort_by(|x, y| x.partial_cmp(y).unwrap());
        b.sort_by(|x, y| x.partial_cmp(y).unwrap());
        assert_eq!(a, b, "{name}");
    }
    assert!(p.validate().first_error().is_none());
}

/// The perturbed law differs from the scene's in the last digits only: μ and κ by 1e-12 to
/// 3e-12 relative, never bit-identical.
#[test]
fn perturbed_material_differs_in_the_last_digits() {
    let specs = newton_krylov_block_specs(&dir("material"), as_built).unwrap();
    let _ = std::fs::remove_dir_all(dir("material"));
    for s in specs.iter().filter(|s| s.variant.poisson_ratio.is_some()) {
        let q = s.variant.apply(s.scene.as_ref().unwrap()).unwrap();
        let before = q.scene.regions[0].material.moduli().unwrap();
        let after = perturb_material(q).unwrap().scene.regions[0].material.moduli().unwrap();
        for (a, b) in [(before.mu, after.mu), (before.kappa, after.kappa)] {
            let rel = (b - a) / a;
            assert!(
                a != b && (0.5 * EPS..=3.0 * EPS).contains(&rel),
                "{} {}: {rel:e}",
                s.row,
                s.value
            );
        }
    }
}

/// Largest ratio of Newton iteration counts between the three runs of a cell. The verdict
/// must be the same; the count may move, because the solver's discrete decisions (line-search
/// acceptance, an active-set change, the forcing term's switch) move with rounding, and the
/// node order also changes the two-level preconditioner's aggregates and so every GMRES
/// solve. A knife edge is a verdict that flips or a count that jumps by an order of
/// magnitude. With the two-level preconditioner a factor 2 bounded what was measured (e.g.
/// 16 mm: 18, 25, 14); the multilevel hierarchy's aggregates follow the node order on every
/// level, and the 34 mm indentation, the block's hardest cell, took 57, 66 and 143 (as built,
/// perturbed, permuted): a factor 3 bounds that, still far from an order of magnitude.
const COUNT_RATIO: f64 = 3.0;

/// T4 at ν = 0.4999 locks (its result is far from T4ANP's, see the Poisson row's note): its
/// verdict is checked, not its count, which follows the locked element's ill-conditioning
/// (measured 79, 78, 30).
fn count_checked(s: &Spec) -> bool {
    !(s.row.contains(", T4,") && s.value == "0.4999")
}

/// The knife-edge test proper: every Newton–Krylov block cell gives the same verdict as it
/// is, with its material perturbed and with the node order permuted, after Newton iteration
/// counts within [`COUNT_RATIO`] of each other. The failure message lists every cell that
/// differs.
#[test]
fn newton_krylov_cells_are_not_on_a_knife_edge() {
    let (a, b) = (dir("as-built"), dir("permuted"));
    let specs = newton_krylov_block_specs(&a, as_built).unwrap();
    let permuted = newton_krylov_block_specs(&b, permute_nodes).unwrap();
    let _ = (std::fs::remove_dir_all(&a), std::fs::remove_dir_all(&b));
    assert_eq!(specs.len(), permuted.len());
    assert!(specs.iter().any(|s| s.row.contains("T4ANP") && s.value == "0.4999"));
    let mut table = String::new();
    let mut differ = 0;
    for (s, p) in specs.iter().zip(&permuted) {
        assert_eq!((&s.row, &s.value), (&p.row, &p.value));
        let ways = [signature(&s.measure()), signature(&perturbed(s)), signature(&p.measure())];
        let same_verdict = ways.iter().all(|w| w.0 == ways[0].0);
        let (lo, hi) = count_range(&ways);
        let close = !count_checked(s) || hi as f64 <= COUNT_RATIO * lo.max(1) as f64;
        let ok = same_verdict && close;
        differ += usize::from(!ok);
        table += &format!(
            "{} {:<52} {:<7} as built: {} in {} | perturbed: {} in {} | permuted: {} in {}\n",
            if ok { " " } else { "!" },
            s.row,
            s.value,
            ways[0].0,
            ways[0].1,
            ways[1].0,
            ways[1].1,
            ways[2].0,
            ways[2].1
        );
    }
    println!("{table}");
    assert_eq!(differ, 0, "{differ} cell(s) on a knife edge (marked !):\n{table}");
}

/// The paper's 40 mm push of the coarse ellipsoid (fixtures/ellipsoid/scene.toml × 4), the
/// cell that was a coin toss in every earlier version (converged, or stalled near 86 % of
/// the load, as Young's modulus moved in the 12th digit; docs/stability.md): as built, with
/// the material perturbed and with the node order permuted, it converges every time, after
/// iteration counts within [`COUNT_RATIO`] of each other. The permuted mesh is written with
/// the fixture's skull into a scene of its own.
#[test]
fn the_40_mm_ellipsoid_is_not_on_a_knife_edge() {
    let fixture = root().join("fixtures/ellipsoid");
    let built = Prepared::load(&fixture.join("scene.toml")).unwrap();
    let v = Variant {
        solver: Some(SolverKind::NewtonKrylov),
        load_factor: Some(4.0),
        ..Variant::default()
    };
    let perturbed = perturb_material(v.apply(&built).unwrap()).unwrap();
    let d = dir("ellipsoid");
    std::fs::create_dir_all(&d).unwrap();
    let mesh = permute_nodes(built.mesh.clone());
    bs_mesh::io::write_mesh(&d.join("brain.inp"), &mesh, &Fields::default()).unwrap();
    let toml = std::fs::read_to_string(fixture.join("scene.toml"))
        .unwrap()
        .replace("brain-coarse.inp", "brain.inp")
        .replace("skull.off", &fixture.join("skull.off").display().to_string());
    std::fs::write(d.join("scene.toml"), toml).unwrap();
    let permuted = Prepared::load(&d.join("scene.toml")).unwrap();
    let _ = std::fs::remove_dir_all(&d);
    let plain = Variant { load_factor: None, ..v.clone() };
    let ways = [
        signature(&measure(&v, &built)),
        signature(&measure(&plain, &perturbed)),
        signature(&measure(&v, &permuted)),
    ];
    println!("as built, perturbed, permuted: {ways:?}");
    let (lo, hi) = count_range(&ways);
    assert!(
        ways.iter().all(|w| w.0 == "converged") && hi as f64 <= COUNT_RATIO * lo as f64,
        "as built, perturbed, permuted: {ways:?}"
    );
}
