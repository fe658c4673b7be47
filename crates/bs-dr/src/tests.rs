//! Test fixtures shared by the unit tests of several layers: the unit right tetrahedron, a
//! distorted mixed mesh (one hex, two tets) and its model.

use bs_material::Material;
use bs_mesh::{Element, Mesh, Point3};

use crate::{Model, ModelOptions, Solid};

/// The unit right tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1): volume 1/6.
pub(crate) fn unit_tet() -> Mesh {
    let nodes = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    Mesh::new(nodes, vec![Element::tet4([0, 1, 2, 3])])
}

/// One distorted hex and two tets sharing nodes with it.
pub(crate) fn distorted_mesh() -> Mesh {
    // One distorted hex (bottom 0-1-2-3, top 4-5-6-7) and two tets sharing nodes with it.
    let nodes = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.1, 0.1, 0.0),
        Point3::new(1.0, 0.9, 0.1),
        Point3::new(-0.1, 1.0, 0.0),
        Point3::new(0.1, 0.0, 1.0),
        Point3::new(1.0, -0.1, 1.2),
        Point3::new(1.2, 1.1, 0.9),
        Point3::new(0.0, 1.0, 1.0),
        Point3::new(0.5, 0.5, 2.0),
    ];
    Mesh::new(
        nodes,
        vec![
            Element::hex8([0, 1, 2, 3, 4, 5, 6, 7]),
            Element::tet4([4, 5, 7, 8]),
            Element::tet4([5, 6, 7, 8]),
        ],
    )
}

/// [`distorted_mesh`] as a Neo-Hookean model (ν = 0.4), T4 tets.
pub(crate) fn model() -> Model {
    let solid = Solid { material: Material::neo_hookean(3000.0, 0.4).unwrap(), density: 1000.0 };
    Model::uniform(&distorted_mesh(), solid, ModelOptions::default()).unwrap()
}
