//! σ of a fitted answer, per node and per landmark (what [`super`]'s sampling gives and a
//! run's result carries).

/// σ of a fitted answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// Per node: σ along x, y, z (scene frame, mesh units).
    pub sigma: Vec<[f64; 3]>,
    /// Per landmark of the scene (in file order): σ of its material point's displacement.
    pub landmarks: Vec<[f64; 3]>,
    /// What the samples drew (the report's `parts`).
    pub parts: Vec<String>,
    /// The held-out landmarks' check and the factor every σ here is already scaled by.
    pub held_out: Option<super::held_out::HeldOutScale>,
    pub samples: usize,
    /// GMRES iterations of all responses, and the wall time of the sampling (seconds).
    pub iterations: usize,
    pub seconds: f64,
    /// GMRES's relative residual per sample, and the factor on σ for that stop (see
    /// [`super::truncation`]).
    pub tolerance: f64,
    pub tolerance_scale: f64,
}

impl Uncertainty {
    /// The total σ at node `a`: `√(σx² + σy² + σz²)`.
    pub fn total(&self, a: usize) -> f64 {
        let [x, y, z] = self.sigma[a];
        (x * x + y * y + z * z).sqrt()
    }
}
