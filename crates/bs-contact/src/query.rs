//! The closest-point query every handler answers (the seam the enforcement loop, the
//! diagnostics and the solver adapter are written against), and its answer, [`Projection`].
//! Modelled on parry's `point_query`: a small trait and a plain result type, apart from any
//! algorithm.

use nalgebra::Point3;

/// A closest-point feature of the master surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Feature {
    /// A master node (vertex index).
    Node(u32),
    /// A master edge (index into `MasterSurface::edges`).
    Edge(u32),
    /// A master face (triangle index).
    Face(u32),
}

/// Closest point of the master surface to a query point, with the paper's inside/outside
/// verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The closest point R on the master surface.
    pub point: Point3<f64>,
    /// Signed distance ±|PR|: positive inside the cavity, negative outside (the same sign
    /// convention as every `signed_distance` of this crate).
    pub signed_distance: f64,
    /// Whether P is outside the cavity (penetrated the skull): `RP · n > 0` with the outward
    /// normal at R (face normal, or summed normal of an edge or node).
    pub outside: bool,
    /// The feature R lies on, when the handler knows it.
    pub feature: Option<Feature>,
}

/// A closest-point query on the master surface: what each contact handler provides. The
/// enforcement loop (`Enforcer`, a module above this one) is generic over it.
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

    /// The exact closest point of `p` at any distance, asked for an answer beyond
    /// [`reach`](Self::reach); `None` when the handler has no other query (the default:
    /// exhaustive handlers are exact everywhere).
    fn closest_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        let _ = p;
        None
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

    fn closest_exact(&self, p: &Point3<f64>) -> Option<Projection> {
        (**self).closest_exact(p)
    }

    fn name(&self) -> &'static str {
        (**self).name()
    }
}
