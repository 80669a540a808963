//! Cameras as the stages read them: a capture's (NeuS `world_mat`s), a JSON file of cameras given by the
//! user, and the transform between two captures' frames.

use crate::error::{err, fail, Context};
use crate::Result;
use geom::{Camera, Pose};
use neus::compose::{prerender_scene, ComposedRay, Composer};
use serde::Deserialize;
use std::path::Path;
use std::time::Instant;

/// An opened capture's cameras, one per image, in its world frame.
pub fn world_cameras(c: &pganeus_io::CaptureIndex) -> Result<Vec<geom::Camera<f64>>> {
    c.cameras
        .iter()
        .enumerate()
        .map(|(i, m)| {
            geom::Camera::from_world_mat(&m.world_mat, c.width, c.height)
                .map_err(|e| err!(Input, "{}: camera {i}: {e}", c.dir.join("cameras_sphere.npz").display()))
        })
        .collect()
}

/// The one camera of a video `c` (in `dir`): every `world_mat` must be the first's.
pub fn fixed_camera(dir: &Path, c: &pganeus_io::CaptureIndex) -> Result<Camera<f64>> {
    let cameras = world_cameras(c)?;
    let m0 = cameras[0].world_mat();
    let scale = m0.iter().flatten().map(|v| v.abs()).fold(1e-12, f64::max);
    for (k, cam) in cameras.iter().enumerate().skip(1) {
        let m = cam.world_mat();
        let diff = m
            .iter()
            .flatten()
            .zip(m0.iter().flatten())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        if diff > 1e-9 * scale {
            fail!(
                Input,
                "{}: world_mat_{k} differs from world_mat_0 (by {diff:.3e}): a video must come from one fixed camera",
                dir.join("cameras_sphere.npz").display()
            );
        }
    }
    Ok(cameras[0])
}

/// The scene through the video's fixed camera, once: what every render of the fit composes its bodies over.
pub fn scene_through(scene: &neus::checkpoint::LoadedField, cam: &Camera<f64>) -> Vec<ComposedRay> {
    let t = Instant::now();
    let pre = prerender_scene(scene, cam, &mut Composer::default());
    tracing::info!(
        "the scene rendered through the video's camera in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    pre
}

/// A camera given by the user.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraJson {
    width: u32,
    height: u32,
    world_mat: Option<[[f64; 4]; 4]>,
    #[serde(rename = "K")]
    k: Option<[[f64; 3]; 3]>,
    world_to_cam: Option<[[f64; 4]; 4]>,
}

pub fn read_cameras(path: &std::path::Path) -> Result<Vec<Camera<f64>>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let list = if value.is_array() {
        value
    } else {
        serde_json::Value::Array(vec![value])
    };
    let cams: Vec<CameraJson> = serde_json::from_value(list).with_context(|| format!("{}", path.display()))?;
    cams.iter()
        .enumerate()
        .map(|(i, c)| {
            let wm = match (c.world_mat, c.k, c.world_to_cam) {
                (Some(w), None, None) => w,
                (None, Some(k), Some(e)) => {
                    let mut w = [[0.0; 4]; 4];
                    for r in 0..3 {
                        for col in 0..4 {
                            w[r][col] = (0..3).map(|l| k[r][l] * e[l][col]).sum();
                        }
                    }
                    w[3] = [0.0, 0.0, 0.0, 1.0];
                    w
                }
                _ => fail!(
                    Input,
                    "{}: camera {i}: give world_mat, or K and world_to_cam",
                    path.display()
                ),
            };
            if c.width == 0 || c.height == 0 {
                fail!(
                    Settings,
                    "{}: camera {i}: width and height must be positive",
                    path.display()
                );
            }
            Camera::from_world_mat(&wm, c.width, c.height).with_context(|| format!("{}: camera {i}", path.display()))
        })
        .collect()
}

/// `p_b = a_to_b · p_a` from a `transform.json` written by `pganeus merge` (or by hand).
pub fn read_transform(path: &std::path::Path) -> Result<Pose<f64>> {
    neus::object_model::read_transform(path).map_err(|e| err!(Stage, "{e}"))
}
