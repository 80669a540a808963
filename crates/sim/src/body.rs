//! A rigid body: its closed mesh in the body frame (origin at the centre of
//! mass), mass properties, contact points, and its SDF for body–body contacts.

use crate::contact::SampleStart;
use crate::contact_points::spread_contact_points;
use crate::mass_properties_mesh::{mass_properties, mesh_volume};
use crate::mesh_check::{check_closed_mesh, MeshCheckError};
use crate::point_clusters::{cluster_points, PointCluster};
use crate::sdf::{SdfGrid, Shape};
use geom::{Mat3, Pose, TriMesh, Vec3};
use std::sync::Arc;

/// How the body's mass is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MassSpec {
    /// Total mass in kg.
    Mass(f64),
    /// Density in kg/m³ (mass = density · volume).
    Density(f64),
}

/// Where the contact points come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ContactSampling {
    /// `count` points spread evenly over the surface and its normals, from `seed` ([`crate::contact_points`]).
    Surface { count: usize, seed: u64 },
    /// The mesh vertices.
    Vertices,
}

impl Default for ContactSampling {
    fn default() -> Self {
        ContactSampling::Surface { count: 1000, seed: 0 }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum BodyError {
    #[error(transparent)]
    Mesh(#[from] MeshCheckError),
    #[error("mass must be positive and finite, got {0}")]
    Mass(f64),
    #[error("density must be positive and finite, got {0}")]
    Density(f64),
    #[error("contact point count must be at least 1")]
    NoContactPoints,
    #[error("a {0} cannot be a body (use a box, sphere, rounded box, capsule, wedge or a closed mesh)")]
    NotASolid(&'static str),
}

#[derive(Clone, Debug)]
pub struct RigidBody {
    pub name: String,
    /// The surface in the body frame (origin at the centre of mass).
    pub mesh: TriMesh,
    pub mass: f64,
    /// Inertia about the centre of mass, body axes.
    pub inertia: Mat3<f64>,
    pub inertia_inv: Mat3<f64>,
    /// Contact points in the body frame (read only: the clusters and the samples' starts are made from them).
    pub contact_points: Vec<Vec3<f64>>,
    /// The contact points grouped by place, for detection ([`crate::point_clusters`]).
    pub(crate) point_clusters: Vec<PointCluster>,
    /// Typical distance between neighbouring contact points, m (√(area / count)).
    pub contact_spacing: f64,
    /// Where each contact point's search for its support starts (found once: the body's own surface).
    pub(crate) sample_starts: Vec<SampleStart>,
    /// Radius of a ball about the origin holding the whole body.
    pub bounding_radius: f64,
    /// Signed distance in the body frame, for contacts with other bodies.
    pub sdf: Shape,
    /// Where the centre of mass was in the frame the mesh was given in:
    /// `p_body = p_given − mesh_offset`.
    pub mesh_offset: Vec3<f64>,
}

impl RigidBody {
    /// A body from an analytic shape (meshed finely for its mass properties
    /// and contact points; its exact SDF serves body–body contacts).
    pub fn from_shape(name: &str, shape: &Shape, mass: MassSpec, sampling: ContactSampling) -> Result<Self, BodyError> {
        let mesh = crate::tessellate::shape_mesh(shape, 24).ok_or(BodyError::NotASolid(match shape {
            Shape::Plane(_) => "plane",
            Shape::Grid(_) => "grid",
            _ => "union",
        }))?;
        Self::from_mesh(name, &mesh, mass, sampling, Some(shape.clone()))
    }

    /// A body from a closed mesh in any frame; the mesh is moved so its centre
    /// of mass is the origin. `sdf` is the body's signed distance in the
    /// mesh's original frame (or `None` to bake one from the mesh).
    pub fn from_mesh(
        name: &str,
        mesh: &TriMesh,
        mass: MassSpec,
        sampling: ContactSampling,
        sdf: Option<Shape>,
    ) -> Result<Self, BodyError> {
        check_closed_mesh(mesh)?;
        let mut mesh = mesh.clone();
        let vol = mesh_volume(&mesh);
        if vol.is_nan() || vol.abs() <= 1e-15 {
            return Err(MeshCheckError::ZeroVolume.into());
        }
        if vol < 0.0 {
            // Consistent but inside out: turn it the right way.
            for f in &mut mesh.faces {
                f.swap(1, 2);
            }
        }
        let m = match mass {
            MassSpec::Mass(m) if m > 0.0 && m.is_finite() => m,
            MassSpec::Mass(m) => return Err(BodyError::Mass(m)),
            MassSpec::Density(d) if d > 0.0 && d.is_finite() => d * vol.abs(),
            MassSpec::Density(d) => return Err(BodyError::Density(d)),
        };
        let props = mass_properties(&mesh, m);
        let com = props.center_of_mass;
        for v in &mut mesh.vertices {
            *v = (Vec3::cst(*v) - com).to_array();
        }
        let contact_points = match sampling {
            ContactSampling::Surface { count: 0, .. } => return Err(BodyError::NoContactPoints),
            ContactSampling::Surface { count, seed } => spread_contact_points(&mesh, count, seed),
            ContactSampling::Vertices => mesh.vertices.iter().map(|v| Vec3::cst(*v)).collect(),
        };
        let contact_spacing = (mesh.area() / contact_points.len() as f64).sqrt();
        let bounding_radius = mesh.vertices.iter().map(|v| Vec3::cst(*v).norm()).fold(0.0, f64::max);
        let sdf = match sdf {
            Some(s) => s.transformed(Pose::from_translation(-com)),
            // 48 cells across is enough for contacts between bodies.
            None => Shape::Grid(Arc::new(
                SdfGrid::from_mesh(&mesh, 48, 6.0).expect("mesh was checked closed"),
            )),
        };
        let inertia_inv = props.inertia.try_inverse().ok_or(BodyError::Mass(m))?;
        let sample_starts = SampleStart::of_samples(&sdf, &contact_points, contact_spacing);
        let point_clusters = cluster_points(&contact_points);
        Ok(Self {
            name: name.to_string(),
            mesh,
            mass: m,
            inertia: props.inertia,
            inertia_inv,
            contact_points,
            point_clusters,
            contact_spacing,
            sample_starts,
            bounding_radius,
            sdf,
            mesh_offset: com,
        })
    }

    /// The principal axes of inertia in the body frame (unit vectors; arbitrary within a plane of equal
    /// moments): the axes a shape symmetric in its mass is symmetric about.
    pub fn principal_axes(&self) -> [Vec3<f64>; 3] {
        let (_, vectors) = geom::symmetric_eigen(self.inertia.m);
        let axes = Mat3::from_rows(vectors);
        std::array::from_fn(|k| axes.col(k).normalize_or(Vec3::new(1.0, 0.0, 0.0)))
    }
}
