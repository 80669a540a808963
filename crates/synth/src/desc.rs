//! The synthetic scene description (TOML): a board, obstacles, textured
//! bodies, light, camera rig and videos. `pganeus synth --print-preset NAME`
//! prints a complete example.

use crate::render::Light;
use crate::texture::Texture;
use serde::{Deserialize, Serialize};
use sim::ContactParams;
use std::path::PathBuf;

/// A shape of an obstacle or a body, in its own frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeDesc {
    Box {
        half: [f64; 3],
    },
    Sphere {
        radius: f64,
    },
    RoundedBox {
        half: [f64; 3],
        radius: f64,
    },
    /// Along z.
    Capsule {
        half_length: f64,
        radius: f64,
    },
    /// A ramp rising towards +x.
    Wedge {
        half: [f64; 3],
    },
    /// A closed PLY or OBJ mesh (relative paths from the scene file).
    Mesh {
        file: PathBuf,
    },
}

/// The calibration board: the slab `|x| ≤ half[0]`, `|y| ≤ half[1]`,
/// `−thickness ≤ z ≤ 0`, lying on an endless table (if any).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Board {
    pub half: [f64; 2],
    pub thickness: f64,
    pub texture: Texture,
    /// The endless table under the board; without one, the board floats in front of the sky (set the sky's
    /// two colours equal for a plain backdrop).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<Texture>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleDesc {
    pub name: String,
    pub shape: ShapeDesc,
    /// Placement: translation and rotation `[w, x, y, z]`.
    pub t: [f64; 3],
    #[serde(default = "identity")]
    pub q: [f64; 4],
    pub texture: Texture,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyDesc {
    pub name: String,
    pub shape: ShapeDesc,
    /// kg.
    pub mass: f64,
    /// Fixed to the body frame, so it moves with the body.
    pub texture: Texture,
    /// Contact points for the simulator (default 1000).
    #[serde(default = "default_points")]
    pub contact_points: usize,
    /// Orientations of the two static captures `<name>_a` and `<name>_b`
    /// (default: upright, and turned over about x). The body rests on the board.
    #[serde(default = "default_static")]
    pub static_orientations: [[f64; 4]; 2],
}

/// Camera settings of the static captures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraRig {
    pub width: u32,
    pub height: u32,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Views per static capture.
    pub views: usize,
    /// Samples per pixel (≥ 4 recommended).
    pub spp: usize,
    /// Elevation range of the background views, degrees above the board.
    pub background_elevation: [f64; 2],
    /// Elevation range of the object views (from above the board only).
    pub object_elevation: [f64; 2],
}

/// The fixed camera of a video.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoCamera {
    /// Degrees above the board (a tripod at a high angle: 35–50).
    pub elevation_deg: f64,
    /// Degrees about z, from +x.
    pub azimuth_deg: f64,
    /// Distance to the look-at point, m.
    pub distance: f64,
    pub look_at: [f64; 3],
}

/// A body's initial state in a video.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoBodyDesc {
    pub name: String,
    pub t: [f64; 3],
    #[serde(default = "identity")]
    pub q: [f64; 4],
    #[serde(default)]
    pub v: [f64; 3],
    #[serde(default)]
    pub omega: [f64; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoDesc {
    pub name: String,
    pub fps: f64,
    pub frames: usize,
    pub substeps: usize,
    pub camera: VideoCamera,
    /// Contact between the bodies and the scene.
    pub contact: ContactParams,
    /// Contact between two bodies (every pair); default: `contact`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pair_contact: Option<ContactParams>,
    pub bodies: Vec<VideoBodyDesc>,
}

/// The engine that makes the videos' motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Physics {
    /// The project's own simulator (the model `fit` assumes): truth.json's `model: "pganeus"`.
    #[default]
    Pganeus,
    /// Rapier, a trusted engine the project did not write (`crate::rapier_motion`): `model: "rapier"`.
    Rapier,
}

impl Physics {
    /// The name truth.json gives the model.
    pub fn model(self) -> &'static str {
        match self {
            Physics::Pganeus => sim::ENGINE,
            Physics::Rapier => "rapier",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SynthScene {
    pub name: String,
    /// What moves the bodies in the videos (default: the project's simulator).
    #[serde(default, skip_serializing_if = "is_default_physics")]
    pub physics: Physics,
    pub board: Board,
    #[serde(default)]
    pub obstacles: Vec<ObstacleDesc>,
    pub bodies: Vec<BodyDesc>,
    #[serde(default)]
    pub light: Light,
    pub cameras: CameraRig,
    pub videos: Vec<VideoDesc>,
}

fn is_default_physics(p: &Physics) -> bool {
    *p == Physics::Pganeus
}

fn identity() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}
fn default_points() -> usize {
    1000
}
fn default_static() -> [[f64; 4]; 2] {
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]
}
