//! Several measurements fitted together: one data term whose springs are those of each
//! measurement, linearised in turn at the same positions.

use bs_dr::{DataTerm, Springs};
use bs_mesh::Point3;

use crate::landmarks::LandmarkFit;
use crate::surface::SurfaceFit;

/// One measurement's data term.
#[derive(Debug, Clone)]
pub enum Term {
    /// A scanned surface (boxed: it holds its planes and grids, a landmark term little).
    Surface(Box<SurfaceFit>),
    /// Landmark pairs.
    Landmarks(LandmarkFit),
}

impl Term {
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs) {
        match self {
            Term::Surface(s) => s.linearise(positions, springs),
            Term::Landmarks(l) => l.linearise(positions, springs),
        }
    }
}

/// Every measurement of a scene as one [`DataTerm`].
#[derive(Debug, Clone, Default)]
pub struct Fits {
    /// The measurements, in scene order.
    pub terms: Vec<Term>,
    scratch: Springs,
}

impl Fits {
    /// The data term of `terms`.
    pub fn new(terms: Vec<Term>) -> Self {
        Fits { terms, scratch: Springs::new() }
    }

    /// Measures every measurement's data against the model at `positions` (for reports).
    pub fn classify(&mut self, positions: &[Point3<f64>]) {
        for t in &mut self.terms {
            match t {
                Term::Surface(s) => s.classify(positions),
                Term::Landmarks(l) => l.classify(positions),
            }
        }
    }
}

impl DataTerm for Fits {
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs) {
        springs.clear();
        for t in &mut self.terms {
            t.linearise(positions, &mut self.scratch);
            springs.extend(&self.scratch);
        }
    }

    fn is_active(&self) -> bool {
        self.terms.iter().any(|t| match t {
            Term::Surface(_) => true,
            Term::Landmarks(l) => l.is_active(),
        })
    }
}
