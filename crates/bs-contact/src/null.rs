//! The null handler: the contact seam's do-nothing implementation.

use nalgebra::Point3;

use crate::query::{ClosestPoint, Projection};

/// The null handler: never finds a slave outside, never moves anything. (bs-dr's
/// `NoContact` is the null implementation of the solver's side of the seam.)
#[derive(Debug, Clone, Copy, Default)]
pub struct NullHandler;

impl ClosestPoint for NullHandler {
    fn closest(&mut self, _slave: usize, _p: &Point3<f64>) -> Option<Projection> {
        None
    }

    fn reach(&self) -> f64 {
        0.0
    }

    fn name(&self) -> &'static str {
        "none"
    }
}
