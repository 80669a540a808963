//! Mass, centre of mass and inertia of a closed mesh of uniform density, by
//! summing signed tetrahedra (origin, a, b, c) — exact for the polyhedron.

use geom::{Mat3, TriMesh, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassProperties {
    pub mass: f64,
    pub volume: f64,
    /// Centre of mass in the mesh's frame.
    pub center_of_mass: Vec3<f64>,
    /// Inertia tensor about the centre of mass, in the mesh's axes.
    pub inertia: Mat3<f64>,
}

/// Volume integrals of the closed mesh: volume, first moment and second moment
/// `∫ x xᵀ dV` about the origin.
fn volume_moments(mesh: &TriMesh) -> (f64, Vec3<f64>, Mat3<f64>) {
    let mut vol = 0.0;
    let mut first = Vec3::zero();
    let mut second = Mat3::<f64>::zero();
    for f in 0..mesh.faces.len() {
        let [a, b, c] = mesh.triangle(f).map(Vec3::<f64>::cst);
        let det = a.dot(b.cross(c));
        vol += det / 6.0;
        let s = a + b + c;
        first += s * (det / 24.0);
        // ∫_tet x xᵀ = det/120 · (a aᵀ + b bᵀ + c cᵀ + s sᵀ)
        let m = Mat3::outer(a, a)
            .add(&Mat3::outer(b, b))
            .add(&Mat3::outer(c, c))
            .add(&Mat3::outer(s, s));
        second = second.add(&m.scale(det / 120.0));
    }
    (vol, first, second)
}

/// Mass properties for a given total `mass` (uniform density). The mesh must
/// be closed and outward oriented (positive volume).
pub fn mass_properties(mesh: &TriMesh, mass: f64) -> MassProperties {
    let (volume, first, second) = volume_moments(mesh);
    let com = first * (1.0 / volume);
    let density = mass / volume;
    // Second moment about the centre of mass, then I = tr(C) 𝟙 − C.
    let c = second.sub(&Mat3::outer(com, com).scale(volume)).scale(density);
    let inertia = Mat3::identity().scale(c.trace()).sub(&c);
    MassProperties {
        mass,
        volume,
        center_of_mass: com,
        inertia,
    }
}

/// The signed volume of a closed mesh (negative when oriented inwards).
pub fn mesh_volume(mesh: &TriMesh) -> f64 {
    volume_moments(mesh).0
}
