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
    /// A calibration board (FORMATS.md "Boards") printed on white paper lying on the board, its pattern
    /// centred on the world's origin; what `calibrate` finds the cameras of raw footage from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub print: Option<calib::BoardSpec>,
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

/// Footage as a camera makes it (`[raw]`): besides the captures with their true cameras, a raw session in
/// `raw/` (FORMATS.md "A raw session"): the same views through a lens with distortion at the sensor's size,
/// held by hand (roll, distance), with exposure and white balance that vary from photo to photo, sensor noise,
/// JPEG, and motion blur in the videos, and close-ups of the printed board (`calibration/`); no cameras and
/// no masks. Needs `board.print`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RawDesc {
    /// The sensor's image size (the field of view is `cameras.fov_deg`, vertical). Default 960 × 720.
    pub width: u32,
    pub height: u32,
    /// OpenCV's `[k1, k2, p1, p2, k3]` of the lens. Default a mild barrel, `[-0.12, 0.05, 0.0004, -0.0003, 0]`.
    pub distortion: [f64; 5],
    /// Sensor noise, standard deviation at mid grey (linear 0–1); shot noise grows with the square root of the
    /// light. Default 0.008.
    pub noise: f64,
    /// JPEG quality, 1–100. Default 90.
    pub jpeg_quality: u8,
    /// Each photo's exposure is off by up to this share. Default 0.06.
    pub exposure_jitter: f64,
    /// Each photo's white balance (per channel) is off by up to this share. Default 0.02.
    pub white_balance_jitter: f64,
    /// A handheld photo is rolled by up to this many degrees about its axis. Default 12.
    pub roll_deg: f64,
    /// ... and its distance to what it looks at is off by up to this share. Default 0.1.
    pub distance_jitter: f64,
    /// How long the shutter is open in a video frame, seconds: moving bodies blur. Default 1/120.
    pub shutter: f64,
    /// Instants averaged over the shutter time. Default 5.
    pub blur_samples: usize,
    /// Seed of the jitter and the noise. Default 1.
    pub seed: u64,
    /// Close-ups of the printed board (`raw/calibration/`) for the lens. Default 12.
    pub calibration_views: usize,
    /// The lens's blur: a Gaussian point spread of this many pixels (σ) at the sensor. Default 0.7.
    pub optical_blur: f64,
}

impl Default for RawDesc {
    fn default() -> Self {
        RawDesc {
            width: 960,
            height: 720,
            distortion: [-0.12, 0.05, 0.0004, -0.0003, 0.0],
            noise: 0.008,
            jpeg_quality: 90,
            exposure_jitter: 0.06,
            white_balance_jitter: 0.02,
            roll_deg: 12.0,
            distance_jitter: 0.1,
            shutter: 1.0 / 120.0,
            blur_samples: 5,
            seed: 1,
            calibration_views: 12,
            optical_blur: 0.7,
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
    /// Also write the footage as a camera makes it (`raw/`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw: Option<RawDesc>,
    /// Render the captures themselves as a camera makes them (with their true cameras and masks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_like: Option<CameraLike>,
}

/// The captures as a camera makes them (`[camera_like]`), at their own size and through their true
/// cameras, their truth (cameras, masks, poses) kept: exposure and white balance that change from photo to
/// photo, a video's auto exposure drifting over its frames, sensor noise and JPEG at the sensor's size
/// (`sensor_scale`), and moving bodies blurred over the shutter time (each video's `capture.json` gives
/// it). A video frame's masks are the bodies at the frame's instant, the middle of its shutter time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraLike {
    /// Sensor noise, standard deviation at mid grey (linear 0–1), growing with the square root of the
    /// light. Default 0.01.
    pub noise: f64,
    /// JPEG quality, 1–100 (the image is JPEG-compressed, then stored as the capture's PNG). Default 85.
    pub jpeg_quality: u8,
    /// Each photo's exposure is off by up to this share. Default 0.1.
    pub exposure_jitter: f64,
    /// Each photo's white balance (per channel) is off by up to this share. Default 0.02.
    pub white_balance_jitter: f64,
    /// A video's exposure drifts over its frames by up to this share (auto exposure). Default 0.08.
    pub exposure_drift: f64,
    /// How long the shutter is open in a video frame, seconds. Default 1/60.
    pub shutter: f64,
    /// Instants averaged over the shutter time, odd (the middle one is the frame's). Default 7.
    pub blur_samples: usize,
    /// The sensor is this many times the capture's size, odd: noise and JPEG are made there and the image
    /// shrunk to the capture's size (mean of each block), as a phone's photo is downsampled for training,
    /// which shrinks their artifacts as much. Default 3; 1 compresses at the capture's size.
    pub sensor_scale: u32,
    /// Seed of the jitter and the noise. Default 1.
    pub seed: u64,
}

impl Default for CameraLike {
    fn default() -> Self {
        CameraLike {
            noise: 0.01,
            jpeg_quality: 85,
            exposure_jitter: 0.1,
            white_balance_jitter: 0.02,
            exposure_drift: 0.08,
            shutter: 1.0 / 60.0,
            blur_samples: 7,
            sensor_scale: 3,
            seed: 1,
        }
    }
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
