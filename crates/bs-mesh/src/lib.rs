//! Meshes for brainshift.
//!
//! * [`Mesh`]: a volume mesh of linear tetrahedra (T4) and 8-node hexahedra (H8), mixed
//!   allowed, with named node and element sets. Coordinates are plain `f64`; the length unit
//!   is carried by the caller (a scene file states it), never assumed here.
//! * [`TriSurface`]: a triangle surface with the topology contact needs
//!   ([`SurfaceTopology`]: node→faces, edges with their faces, normals, closedness,
//!   manifoldness and orientation checks).
//! * [`BoundarySurface`]: the outward-oriented boundary of a volume mesh with the map back to
//!   volume node indices.
//! * [`validate`](Mesh::validate): typed [`MeshError`]s for inverted or degenerate elements,
//!   out-of-range or duplicate nodes, unused nodes.
//! * [`TriSurface::self_intersections`]: triangle pairs of a surface that cross each other
//!   (a bucket grid over a robust triangle–triangle test), part of the skull check
//!   [`TriSurface::require_closed_outward`].
//! * [`TetLocator`]: point location in a tetrahedral mesh, to carry a nodal field onto the
//!   nodes of another mesh ([`transfer`]); [`lattice`]: every point of a regular lattice
//!   (an image's voxel centres) located at once by rasterising the tetrahedra, in parallel;
//!   [`lattice_inside`]: the lattice points inside a closed surface (a skull cavity).
//! * [`io`]: readers and writers for Abaqus `.inp`, Gmsh `.msh` (2.2 and 4.1, ASCII or binary), VTK
//!   legacy, VTU, STL, OBJ and OFF. Every parse error names the file and line (or byte
//!   offset) and what was expected.
//! * [`tps`]: thin-plate spline interpolation of a vector field from landmarks (loads from
//!   intra-operative landmark pairs).
//! * [`structured`]: structured box meshes (hexahedra or Kuhn tetrahedra, optionally
//!   jittered) and [`rng`], the workspace's one seeded generator for tests and benchmarks.
//!
//! ```
//! use bs_mesh::{Element, Mesh, Point3};
//!
//! // One unit hexahedron (Abaqus/VTK node order): validate it, take its outward boundary.
//! let nodes = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.],
//!              [0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]].map(Point3::from);
//! let mesh = Mesh::new(nodes.to_vec(), vec![Element::hex8([0, 1, 2, 3, 4, 5, 6, 7])]);
//! assert!(mesh.validate().first_error().is_none());
//! let boundary = mesh.boundary(); // quads split: 12 outward triangles
//! assert_eq!(boundary.surface.triangles.len(), 12);
//! assert!(boundary.surface.check().unwrap().is_closed_outward());
//! // The same box as six Kuhn tetrahedra, and a 3×3×3 grid of them.
//! let tets = bs_mesh::structured::box_mesh(3, 1.0, true);
//! assert_eq!(tets.elements.len(), 6 * 27);
//! ```
//!
//! Files:
//! * `mesh.rs`: `Mesh`, `Element`, `ElementKind`, node and element ids and sets;
//! * `validate.rs`: `Mesh::validate`, `MeshError` and `ValidationReport`;
//! * `boundary.rs`: `BoundarySurface`, the outward boundary with its map to volume nodes;
//! * `surface.rs`: `TriSurface` and `SurfaceTopology` (node→faces, edges, normals);
//! * `surface_check.rs`: `SurfaceCheck`, the checks a skull must pass, and
//!   `require_closed_outward`;
//! * `self_intersection.rs` (tests in `self_intersection/tests.rs`): crossing triangle pairs;
//! * `closest.rs`: the one point–triangle closest-point query with its Voronoi region;
//! * `locate.rs`: `TetLocator`, `Location` and `transfer` (a nodal field onto other points);
//! * `lattice.rs`: `LatticeLocation`, every lattice point located by rasterising the
//!   tetrahedra, and `tetrahedra` (hexes split into Kuhn tetrahedra); `lattice/affine.rs`:
//!   `TetAffine`, one affine map of the lattice indices per tetrahedron, and `map_inside`;
//! * `lattice_inside.rs`: `inside_closed_surface`, the lattice points inside a closed surface;
//! * `quality.rs`: radius ratio, scaled Jacobian, `summary` and `mean_edge_length`;
//! * `tps.rs`: `ThinPlateSpline`, landmark displacements carried to other points;
//! * `structured.rs`: `box_mesh`, `cuboid_mesh`, `jittered_box_mesh`, `box_with_ball`;
//! * `rng.rs`: `SplitMix64`, the workspace's one seeded generator;
//! * `io/`: `mod.rs` (`read`, `read_mesh`, `read_surface`, `write_mesh`,
//!   `write_mesh_in_space`, `write_surface`, `Format`, `Fields`, `ParseError`,
//!   `MeshIoError`), `inp/` (`read.rs`, `write.rs`), `msh/` (`ascii.rs`, `binary.rs`,
//!   `state.rs`, what both share), `vtk.rs` (legacy), `vtu/` (`read.rs`, `write.rs`,
//!   `cells.rs`, the cell model shared with `vtk.rs`), `stl.rs`, `obj.rs`, `off.rs`, `ply.rs`
//!   (PLY vertices) and `points.rs` (`read_points`: point clouds by extension).
//!
//! Architecture invariant: this crate knows nothing about materials, solvers or contact. It
//! depends on no brainshift crate but bs-atomic (every file it writes is written atomically).

mod boundary;
pub mod closest;
pub mod io;
pub mod lattice;
pub mod lattice_inside;
mod locate;
mod mesh;
pub mod quality;
pub mod rng;
pub mod self_intersection;
pub mod structured;
mod surface;
mod surface_check;
pub mod tps;
mod validate;

pub use boundary::BoundarySurface;
pub use locate::{LocateError, Location, TetLocator, transfer};
pub use mesh::{Element, ElementKind, HEX_REFERENCE, Mesh};
/// The linear algebra of every coordinate here, re-exported so that callers need no
/// separate dependency.
pub use nalgebra;
pub use nalgebra::{Point3, Vector3};
pub use surface::{Edge, SelfIntersection, SurfaceError, SurfaceTopology, TriSurface};
pub use surface_check::SurfaceCheck;
pub use validate::{MeshError, ValidationReport};
