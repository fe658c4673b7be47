//! The shared enforcement loop, the closest-point trait every handler implements, the
//! initial-state check and the gap diagnostic.

use nalgebra::Point3;

use crate::ContactError;
use crate::brute::BruteForce;
use crate::master::{Feature, MasterSurface};

/// Closest point of the master surface to a query point, with the paper's inside/outside
/// verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The closest point R on the master surface.
    pub point: Point3<f64>,
    /// Signed distance |PR|: positive inside the cavity, negative outside.
    pub distance: f64,
    /// Whether P is outside the cavity (penetrated the skull): `RP · n > 0` with the outward
    /// normal at R (face normal, or summed normal of an edge or node).
    pub outside: bool,
    /// The feature R lies on, when the handler knows it.
    pub feature: Option<Feature>,
}

/// A closest-point query on the master surface: what each contact handler provides. The
/// enforcement loop ([`Enforcer`]) is generic over it.
pub trait ClosestPoint {
    /// Closest point to `p`, the current position of slave number `slave` (its index in the
    /// slave list; handlers with per-slave state use it).
    ///
    /// `None` means the handler certifies that `p` needs no correction (it is inside the
    /// cavity) without having computed the closest point. Within [`reach`](Self::reach) of
    /// the surface a `Some` answer is the exact closest point.
    fn closest(&mut self, slave: usize, p: &Point3<f64>) -> Option<Projection>;

    /// Distance from the surface (either side) within which answers are exact: infinite for
    /// exhaustive handlers, the per-step penetration bound `d` for the paper's algorithm.
    fn reach(&self) -> f64 {
        f64::INFINITY
    }

    /// Short name for reports and benchmarks.
    fn name(&self) -> &'static str;
}

impl<H: ClosestPoint + ?Sized> ClosestPoint for &mut H {
    #[inline]
    fn closest(&mut self, slave: usize, p: &Point3<f64>) -> Option<Projection> {
        (**self).closest(slave, p)
    }

    fn reach(&self) -> f64 {
        (**self).reach()
    }

    fn name(&self) -> &'static str {
        (**self).name()
    }
}

/// What one enforcement pass did. Same shape as the solver's `ContactReport`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnforceReport {
    /// Slave nodes found outside the cavity and moved to the surface.
    pub nodes_in_contact: usize,
    /// Largest distance by which a slave was outside before correction (0 if none).
    pub max_penetration: f64,
}

/// Kinematic contact enforcement: after each solver step every slave node outside the
/// cavity is moved to its closest point on the master surface. Inside nodes are not touched.
#[derive(Debug, Clone)]
pub struct Enforcer<H> {
    handler: H,
    slaves: Vec<usize>,
    /// Processing order of the slaves (positions in `slaves`), spatially sorted at the first
    /// call so that consecutive queries touch nearby master data (cache locality). The order
    /// does not change any result: each slave is corrected independently.
    order: Vec<u32>,
}

impl<H: ClosestPoint> Enforcer<H> {
    /// An enforcer for the slave nodes `slaves` (indices into the positions array, which has
    /// `node_count` entries).
    pub fn new(handler: H, slaves: Vec<usize>, node_count: usize) -> Result<Self, ContactError> {
        if let Some(&node) = slaves.iter().find(|&&s| s >= node_count) {
            return Err(ContactError::SlaveOutOfRange { node, node_count });
        }
        Ok(Self { handler, slaves, order: Vec::new() })
    }

    /// Moves every slave that is outside the cavity to the closest point of the master
    /// surface. `positions` are the current coordinates of all mesh nodes. No allocation.
    pub fn enforce(&mut self, positions: &mut [Point3<f64>]) -> EnforceReport {
        if self.order.len() != self.slaves.len() {
            self.order = spatial_order(&self.slaves, positions);
        }
        let mut report = EnforceReport::default();
        for &k in &self.order {
            let k = k as usize;
            let Some(p) = positions.get_mut(self.slaves[k]) else { continue };
            if let Some(proj) = self.handler.closest(k, p)
                && proj.outside
            {
                report.nodes_in_contact += 1;
                report.max_penetration = report.max_penetration.max(-proj.distance);
                *p = proj.point;
            }
        }
        report
    }

    /// The slave node indices.
    pub fn slaves(&self) -> &[usize] {
        &self.slaves
    }

    /// The handler.
    pub fn handler(&self) -> &H {
        &self.handler
    }

    /// The handler, mutably.
    pub fn handler_mut(&mut self) -> &mut H {
        &mut self.handler
    }
}

/// Positions in `slaves` sorted by the Morton (Z-order) code of the slave positions.
fn spatial_order(slaves: &[usize], positions: &[Point3<f64>]) -> Vec<u32> {
    let pts: Vec<Point3<f64>> =
        slaves.iter().map(|&s| positions.get(s).copied().unwrap_or_else(Point3::origin)).collect();
    let (lo, hi) = crate::master::bounds(pts.iter());
    let spread = |v: u64| {
        // Spread the low 21 bits of v to every third bit.
        let mut x = v & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    };
    let code = |p: &Point3<f64>| {
        let mut c = 0u64;
        for k in 0..3 {
            let ext = hi[k] - lo[k];
            let t = if ext > 0.0 && ext.is_finite() {
                ((p[k] - lo[k]) / ext).clamp(0.0, 1.0)
            } else {
                0.0
            };
            c |= spread((t * 1_048_575.0) as u64) << k;
        }
        c
    };
    let mut order: Vec<u32> = (0..slaves.len() as u32).collect();
    order.sort_by_key(|&k| code(&pts[k as usize]));
    order
}

/// A slave node found outside the cavity before the first step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutsideNode {
    /// Index of the node in the positions array.
    pub node: usize,
    /// Signed distance (negative: how far outside).
    pub signed_distance: f64,
    /// Closest point of the skull.
    pub closest: Point3<f64>,
}

/// Lists the slave nodes that are outside the cavity at the start, exactly (brute force over
/// every face, run once). An empty list means the initial state is admissible; otherwise the
/// caller should report the nodes (or project them first, knowingly).
pub fn check_initial(
    master: &MasterSurface,
    slaves: &[usize],
    positions: &[Point3<f64>],
) -> Result<Vec<OutsideNode>, ContactError> {
    let brute = BruteForce::from_master(std::sync::Arc::new(master.clone()));
    let mut out = Vec::new();
    for &node in slaves {
        let p = positions
            .get(node)
            .ok_or(ContactError::SlaveOutOfRange { node, node_count: positions.len() })?;
        let proj = brute.project(p);
        if proj.outside {
            out.push(OutsideNode { node, signed_distance: proj.distance, closest: proj.point });
        }
    }
    Ok(out)
}

/// One row of the gap diagnostic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapRow {
    /// Signed distance to the skull: positive inside the cavity, negative outside.
    pub signed_distance: f64,
    /// Closest point on the skull.
    pub closest: Point3<f64>,
    /// Whether the point is outside the cavity.
    pub outside: bool,
}

/// The gap diagnostic (`brainshift gap`): for each query point the exact signed distance to
/// the skull, the closest point and the outside verdict, computed with `handler`. Where the
/// handler gives no answer or the point is farther from the surface than the handler's
/// [`reach`](ClosestPoint::reach) (the paper's algorithm is exact only within the per-step
/// penetration bound `d`), the row is computed by brute force, so every row is exact.
pub fn gap<H: ClosestPoint>(
    handler: &mut H,
    master: &MasterSurface,
    points: &[Point3<f64>],
) -> Vec<GapRow> {
    let brute = BruteForce::from_master(std::sync::Arc::new(master.clone()));
    let reach = handler.reach();
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let proj = match handler.closest(i, p) {
                Some(proj) if proj.distance.abs() <= reach => proj,
                _ => brute.project(p),
            };
            GapRow { signed_distance: proj.distance, closest: proj.point, outside: proj.outside }
        })
        .collect()
}
