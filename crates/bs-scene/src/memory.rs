//! Memory: a run's peak estimated before anything large is allocated, and refused when it
//! exceeds what the machine has.

use crate::SceneError;
use crate::prepare::Prepared;
use crate::scene::SolverKind;

/// Rough peak memory of a run (bytes).
///
/// Dynamic Relaxation, calibrated on fixtures/mni152 (13 975 nodes, 69 140 tets, 8982 skull
/// triangles: 61 MB peak resident measured with /usr/bin/time): about 600 B per node (mesh,
/// solver vectors, boundary), 600 B per tet (mesh element, precomputed gradients, force
/// slots, assembly map), 2.5 kB per hex (adds the 8×8 hourglass matrix) and 1.5 kB per skull
/// triangle (topology, buckets, additional lists, coherence tables).
///
/// Newton–Krylov adds per node the GMRES basis (81 nodal vectors) and the preconditioner
/// (stiffness blocks in double and single precision, the nodal volumetric terms, the
/// prolongator, and `K₀`, `P` and `K₀ P` kept to rebuild the coarse matrix for the contact
/// set), and a base for the coarse factor: 13.8 kB per node, 1 kB per tet, 12 MB; fitted on
/// the three MNI152 meshes (peak resident 118, 286 and 613 MB for 5021, 13 975 and
/// 31 006 nodes, `/usr/bin/time`, 2026-11-28; within 1 %).
pub fn estimate(p: &Prepared) -> f64 {
    let (tets, hexes) = p.mesh.count_by_kind();
    let nodes = p.mesh.nodes.len() as f64;
    let skull = p.skull.as_ref().map_or(0, |s| s.triangles.len()) as f64;
    match p.scene.solver.kind {
        SolverKind::NewtonKrylov => {
            12e6 + nodes * 13_800.0 + tets as f64 * 1000.0 + hexes as f64 * 3500.0 + skull * 1500.0
        }
        SolverKind::Dr | SolverKind::Newton => {
            nodes * 600.0 + tets as f64 * 600.0 + hexes as f64 * 2500.0 + skull * 1500.0
        }
    }
}

/// Memory available to a new allocation on this machine (bytes): `MemAvailable` of
/// `/proc/meminfo`; `None` where that cannot be read (then nothing is refused).
pub fn available() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
}

fn parse_meminfo(text: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// Refuses a run whose estimate exceeds `available` bytes (no limit when `None`).
pub fn require_fits(p: &Prepared, available: Option<f64>) -> Result<(), SceneError> {
    let estimate_bytes = estimate(p);
    match available {
        Some(available_bytes) if estimate_bytes > available_bytes => {
            Err(SceneError::Memory { scene: p.path.clone(), estimate_bytes, available_bytes })
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_is_read_in_kib() {
        let text = "MemTotal:       24576000 kB\nMemFree:  1000 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(parse_meminfo(text), Some(2048.0 * 1024.0));
        assert_eq!(parse_meminfo("MemTotal: 5 kB\n"), None);
    }

    /// A scene whose estimate exceeds the limit is refused before anything is composed,
    /// naming both figures; within the limit, or with no limit known, it passes.
    #[test]
    fn a_scene_above_the_available_memory_is_refused() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/cube/uniaxial-t4.toml");
        let p = Prepared::load(&path).unwrap();
        let need = estimate(&p);
        assert!(need > 1e6, "{need}");
        match require_fits(&p, Some(need / 2.0)) {
            Err(e @ SceneError::Memory { .. }) => {
                let text = e.to_string();
                assert!(text.contains("needs about") && text.contains("available"), "{text}");
            }
            other => panic!("expected a memory error, got {other:?}"),
        }
        assert!(require_fits(&p, Some(need * 2.0)).is_ok());
        assert!(require_fits(&p, None).is_ok());
    }
}
