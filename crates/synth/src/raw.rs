//! Raw footage (`[raw]`): the captures' views as a camera makes them — through a lens with distortion at
//! the sensor's size, with per-photo exposure and white balance, sensor noise, JPEG, and motion blur in the
//! videos — written as plain image folders with the board's file (FORMATS.md "A raw session"); the true
//! lens beside them in `camera_truth.json`.

use crate::desc::{RawDesc, SynthScene};
use crate::render::{render_instants, RenderScene, Rendered};
use calib::Lens;
use geom::{Camera, Pose, Quat, Ray, SplitMix64, Vec3};
use pganeus_io::Image;
use std::path::Path;

/// The raw lens: the rig's field of view at the sensor's size, the principal point a little off centre (as
/// real sensors sit), OpenCV's convention (pixel centres at integers).
pub fn raw_lens(scene: &SynthScene, raw: &RawDesc) -> Lens {
    let fy = 0.5 * raw.height as f64 / (0.5 * scene.cameras.fov_deg.to_radians()).tan();
    let (w, h) = (raw.width as f64, raw.height as f64);
    Lens {
        fx: fy * 1.0015,
        fy,
        cx: (w - 1.0) / 2.0 + 0.004 * w,
        cy: (h - 1.0) / 2.0 - 0.003 * h,
        distortion: raw.distortion,
    }
}

/// A camera moved as a hand holds it: rolled about its axis and nearer or farther from what it looks at
/// (`target_distance` along its axis), by the draws of `rng`.
pub fn handheld(camera: &Camera<f64>, target_distance: f64, raw: &RawDesc, rng: &mut SplitMix64) -> Camera<f64> {
    let c2w = camera.world_to_cam.inverse();
    let forward = c2w.transform_vector(Vec3::new(0.0, 0.0, 1.0));
    let target = c2w.t + forward * target_distance;
    let distance = target_distance * (1.0 + rng.range(-raw.distance_jitter, raw.distance_jitter));
    let roll = rng.range(-raw.roll_deg, raw.roll_deg).to_radians();
    // Roll: a turn about the camera's z axis, applied in the camera frame.
    let q = Quat::exp(Vec3::new(0.0, 0.0, roll)) * camera.world_to_cam.q;
    let centre = target - forward * distance;
    let world_to_cam = Pose::new(q, -(q.rotate(centre)));
    Camera {
        world_to_cam,
        ..*camera
    }
}

/// The world ray through image position `(u, v)` (pixel centres at integer + 0.5) of a camera posed
/// `world_to_cam` with `lens`.
fn lens_ray(lens: &Lens, world_to_cam: &Pose<f64>, u: f64, v: f64) -> Ray<f64> {
    let [x, y] = lens.undistort(u - 0.5, v - 0.5);
    let c2w = world_to_cam.inverse();
    Ray {
        origin: c2w.t,
        dir: c2w
            .transform_vector(Vec3::new(x, y, 1.0))
            .normalize_or(Vec3::new(0.0, 0.0, 1.0)),
    }
}

/// One raw image: `scenes` (one instant, or the instants of a shutter time) seen through the lens, averaged.
pub fn render_raw(
    scenes: &[RenderScene],
    world_to_cam: &Pose<f64>,
    lens: &Lens,
    raw: &RawDesc,
    spp: usize,
) -> Rendered {
    let ray = |u: f64, v: f64| lens_ray(lens, world_to_cam, u, v);
    let mut out = render_instants(scenes, raw.width, raw.height, spp, None, &ray);
    optical_blur(&mut out, raw.optical_blur);
    out
}

/// The lens's point spread: a Gaussian of `sigma` pixels over the linear image (no lens is sharper than a
/// pixel or two, and a point-sampled edge without it has a stair-step no camera makes).
fn optical_blur(r: &mut Rendered, sigma: f64) {
    if sigma <= 0.0 {
        return;
    }
    let radius = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();
    let (w, h) = (r.width as i64, r.height as i64);
    for pass in 0..2 {
        let src = r.rgb.clone();
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0.0f32; 3];
                for (k, weight) in kernel.iter().enumerate() {
                    let d = k as i64 - radius;
                    let (sx, sy) = if pass == 0 {
                        ((x + d).clamp(0, w - 1), y)
                    } else {
                        (x, (y + d).clamp(0, h - 1))
                    };
                    let v = src[(sy * w + sx) as usize];
                    for c in 0..3 {
                        acc[c] += weight * v[c];
                    }
                }
                r.rgb[(y * w + x) as usize] = acc;
            }
        }
    }
}

/// The light a sensor records: exposure and white balance (`gain` per channel), shot and read noise, then
/// the camera's sRGB encoding.
pub fn develop(r: &Rendered, gain: [f64; 3], noise: f64, rng: &mut SplitMix64) -> Image {
    let mut img = Image::new(r.width, r.height, 3);
    for (px, c) in img.data.chunks_exact_mut(3).zip(&r.rgb) {
        for k in 0..3 {
            let light = c[k] as f64 * gain[k];
            // σ = noise at mid grey, growing with the square root of the light (shot noise) over a floor.
            let sigma = noise * ((light + 0.02) / 0.52).sqrt();
            let gauss =
                (-2.0 * rng.next_f64().max(1e-300).ln()).sqrt() * (std::f64::consts::TAU * rng.next_f64()).cos();
            px[k] = crate::render::to_srgb8((light + sigma * gauss) as f32);
        }
    }
    img
}

/// Exposure and white balance of one photo: each off by up to its share.
pub fn photo_gain(exposure_jitter: f64, white_balance_jitter: f64, rng: &mut SplitMix64) -> [f64; 3] {
    let exposure = 1.0 + rng.range(-exposure_jitter, exposure_jitter);
    std::array::from_fn(|_| exposure * (1.0 + rng.range(-white_balance_jitter, white_balance_jitter)))
}

/// The raw file name of image `i` of a capture: photos `IMG_0001.jpg`, a video's frames `<name>_0000.jpg`.
pub fn raw_name(capture: &str, video: bool, i: usize) -> String {
    if video {
        format!("{capture}_{i:04}.jpg")
    } else {
        format!("IMG_{:04}.jpg", i + 1)
    }
}

/// `camera_truth.json`: the true lens (OpenCV's convention) and which truth capture each raw folder is.
pub fn camera_truth(lens: &Lens, raw: &RawDesc, captures: &[(String, Vec<String>)]) -> serde_json::Value {
    serde_json::json!({
        "lens": {"K": [[lens.fx, 0.0, lens.cx], [0.0, lens.fy, lens.cy], [0.0, 0.0, 1.0]], "distortion": lens.distortion},
        "image_size": [raw.width, raw.height],
        "conventions": "lens.K: OpenCV's (pixel centres at integers), raw images. Each raw folder's images are the views of the capture of the same name beside raw/ (its cameras_sphere.npz: the same poses, a distortion-free camera at the captures' size), in the same order.",
        "captures": captures.iter().map(|(name, files)| serde_json::json!({"name": name, "files": files})).collect::<Vec<_>>(),
    })
}

/// Writes `text` to `dir/name` atomically.
pub fn write_text(dir: &Path, name: &str, text: &str) -> Result<(), pganeus_io::IoError> {
    pganeus_io::write_atomic(&dir.join(name), text.as_bytes())
}
