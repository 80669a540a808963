//! The differentiable rigid-body solver of PGA-NeuS (Sec. 3.3, Eq. 5–8):
//! semi-implicit Euler with substeps (exact parabolas in free flight), gravity and damping, SDF contacts against
//! a static scene and between bodies (threshold Δ and the velocity condition
//! of Eq. 8, impulse at the averaged contact point with restitution `k_n` and
//! friction `mu`), and exact derivatives of every output by dual numbers.

pub mod body;
pub mod config;
mod contact;
pub mod contact_points;
pub mod contact_query;
pub mod gradients;
pub mod mass_properties_mesh;
pub mod mesh_check;
pub mod point_clusters;
pub mod sample_surface;
pub mod sdf;
pub mod state;
pub mod tessellate;
pub mod world;

pub use body::{BodyError, ContactSampling, MassSpec, RigidBody};
pub use config::{ConfigError, ContactModel, ContactParams, FrictionModel, SimConfig};
pub use contact_query::{points_near_scene, NearPoint};
pub use gradients::{simulate_with_gradients, TrajectoryGrad};
pub use mass_properties_mesh::{mass_properties, MassProperties};
pub use mesh_check::{check_closed_mesh, MeshCheckError};
pub use state::{BodyState, STATE_LEN};
/// This engine's name where a file records which engine made a motion (`contact.model` of a trajectory file).
pub const ENGINE: &str = "pganeus";

pub use world::{FrameContacts, Trajectory, World, BODY_PARAMS, BODY_PARAM_NAMES, PAIR_PARAMS};
