//! Mass properties of meshed shapes against their formulas; moving the mesh
//! moves the centre of mass by the same amount.
use geom::{TriMesh, Vec3};
use sim::sdf::{Cuboid, Sphere};
use sim::tessellate::{cuboid_mesh, sphere_mesh};
use sim::{check_closed_mesh, mass_properties, MeshCheckError};

#[test]
fn box_inertia_matches_formula() {
    let half = [0.05, 0.02, 0.01];
    let m = 0.3;
    for n in [1, 3] {
        let mesh = cuboid_mesh(&Cuboid { half }, n);
        check_closed_mesh(&mesh).unwrap();
        let p = mass_properties(&mesh, m);
        let (a, b, c) = (2.0 * half[0], 2.0 * half[1], 2.0 * half[2]);
        assert!((p.volume - a * b * c).abs() < 1e-15);
        let expect = [
            m / 12.0 * (b * b + c * c),
            m / 12.0 * (a * a + c * c),
            m / 12.0 * (a * a + b * b),
        ];
        for i in 0..3 {
            assert!(
                (p.inertia.m[i][i] - expect[i]).abs() < 1e-12 * expect[i].max(1e-9) + 1e-15,
                "I[{i}{i}]"
            );
            for j in 0..3 {
                if i != j {
                    assert!(p.inertia.m[i][j].abs() < 1e-15, "off-diagonal I[{i}{j}]");
                }
            }
        }
        assert!(p.center_of_mass.norm() < 1e-15);
    }
}

#[test]
fn sphere_mesh_approaches_solid_sphere() {
    let r = 0.03;
    let mesh = sphere_mesh(&Sphere { radius: r }, 24);
    check_closed_mesh(&mesh).unwrap();
    let p = mass_properties(&mesh, 1.0);
    let v = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    assert!((p.volume - v).abs() / v < 5e-3, "volume {} vs {v}", p.volume);
    let i = 0.4 * r * r;
    for k in 0..3 {
        assert!((p.inertia.m[k][k] - i).abs() / i < 1e-2);
    }
}

#[test]
fn moving_the_mesh_moves_the_centre_of_mass() {
    let mesh = cuboid_mesh(
        &Cuboid {
            half: [0.05, 0.02, 0.01],
        },
        2,
    );
    let shift = Vec3::new(0.3, -0.1, 0.7);
    let moved = TriMesh::new(
        mesh.vertices
            .iter()
            .map(|v| (Vec3::cst(*v) + shift).to_array())
            .collect(),
        mesh.faces.clone(),
    );
    let (a, b) = (mass_properties(&mesh, 1.0), mass_properties(&moved, 1.0));
    assert!((b.center_of_mass - a.center_of_mass - shift).norm() < 1e-12);
    for i in 0..3 {
        for j in 0..3 {
            assert!(
                (a.inertia.m[i][j] - b.inertia.m[i][j]).abs() < 1e-12,
                "inertia about the COM is unchanged"
            );
        }
    }
}

#[test]
fn open_mesh_is_rejected() {
    let mut mesh = cuboid_mesh(
        &Cuboid {
            half: [0.05, 0.02, 0.01],
        },
        1,
    );
    mesh.faces.pop();
    assert!(matches!(check_closed_mesh(&mesh), Err(MeshCheckError::Open { .. })));
}
