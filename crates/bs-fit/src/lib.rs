//! Intra-operative measurements fitted with the biomechanical model as the regulariser.
//!
//! Imposing measured displacements node by node turns the measurement's noise into
//! fictitious forces: half a millimetre of noise inverts surface elements, an outlier tears
//! the surface, a partial scan leaves nodes without a value. Here a measurement is an
//! energy added to the model's (bs-dr's [`DataTerm`](bs_dr::DataTerm) seam), so the answer
//! minimises
//!
//! `Π(u) + Σ_i k_i ρ(r_i(u) / s)`
//!
//! over the displacements `u`, with `Π` the hyperelastic strain energy (and the skull as a
//! constraint), `r_i` the distance of measured point `i` from the deformed brain, `k_i` its
//! stiffness, `ρ` Tukey's biweight at the robust scale `s ≥ σ`. The solver linearises the
//! data term once per Newton iteration (Gauss–Newton on the data, point-to-plane), so the
//! fit is a steady state of the same machinery as a prescribed load. `docs/fit.md` derives
//! the weights and measures the result.
//!
//! * [`surface`]: a scanned surface (laser range scanner, stereo camera) fitted
//!   point-to-surface on the exposed patch, density-independent weights per face
//!   (`SurfaceFit`, `surface_stiffness`); `surface/plane.rs` the robust plane of the scan
//!   near one point (moving least squares of degree one), `surface/slide.rs` the prior on
//!   the patch sliding along itself (`Slide`, `slide_stiffness`), `surface/tests.rs`;
//! * [`landmarks`]: landmark pairs (tracked ultrasound, a pointer) measured point-to-point
//!   at material points inside the brain (`LandmarkFit`, `Anchor`);
//! * [`boundary_fit`]: landmarks fitted through a small basis of fields on the boundary the
//!   shift comes from (`basis`, `chord_fit`: Tukey-weighted, discrepancy-regularised
//!   Gauss–Newton on the amplitudes, the model a closure);
//! * [`rigid`]: the scan's rigid misalignment, estimated from points on bone (`fit_rigid`),
//!   with its posterior covariance;
//! * [`robust`]: the scale estimate and the biweight;
//! * `density.rs`: the area each scan point stands for;
//! * `fits.rs`: several measurements as one data term (`Fits`, `Term`);
//! * [`synthetic`]: a sensor model (a known surface scanned with noise, partial coverage,
//!   outliers and misalignment), for studies and tests.
//!
//! Architecture invariant: bs-fit knows points, triangles, material points (nodes and
//! weights) and bs-dr's data seam (it depends on bs-mesh, bs-contact for the patch's closest
//! points, and bs-dr); it reads no files and knows no scene (bs-scene builds its terms), no
//! elements and no solver internals.

pub mod boundary_fit;
pub mod density;
pub mod fits;
pub mod landmarks;
pub mod rigid;
pub mod robust;
pub mod surface;
pub mod synthetic;

pub use fits::{Fits, Term};
pub use landmarks::{Anchor, LandmarkFit};
pub use rigid::{Rigid, RigidError, RigidFit, RigidParams, fit_rigid};
pub use surface::slide::{Slide, slide_stiffness};
pub use surface::{PointFit, PointStatus, SurfaceFit, SurfaceParams, surface_stiffness};
