//! A capture in the NeuS layout from raw images whose cameras are known (by `calibrate` or an imported
//! reconstruction): each image undistorted through an ideal pinhole scaled to the capture's width,
//! `cameras_sphere.npz` in the world's metres, `capture.json`.

use std::path::{Path, PathBuf};

use calib::region::{looked_at_region, seen_table_region, Looking};
use calib::undistort::{scaled_pinhole, undistort_image};
use calib::Lens;
use geom::{Pose, Vec3};
use pganeus_io::{CameraMats, CaptureInfo};
use rayon::prelude::*;

use crate::error::{err, fail};
use crate::{Result, Task};

/// One image of a capture: its raw file, its lens (OpenCV's convention, raw pixels), its world-to-camera pose.
#[derive(Clone, Debug)]
pub struct SourceImage {
    pub path: PathBuf,
    pub lens: Lens,
    pub pose: Pose<f64>,
}

/// The capture's pixel size for raw images of `raw` size at `width` (the height keeps the aspect), and the
/// scale from raw to capture pixels.
pub fn capture_size(raw: (usize, usize), width: u32) -> Result<(u32, u32, f64)> {
    if width < 16 || width as usize > 4 * raw.0 {
        fail!(Settings, "--width {width}: between 16 and {} pixels", 4 * raw.0);
    }
    let scale = width as f64 / raw.0 as f64;
    Ok((width, (raw.1 as f64 * scale).round() as u32, scale))
}

/// The pinhole a raw lens's images are undistorted through, at `scale` (capture pixels per raw pixel).
pub fn capture_pinhole(lens: &Lens, scale: f64) -> Lens {
    scaled_pinhole(&Lens::pinhole(lens.fx, lens.fy, lens.cx, lens.cy), scale)
}

/// The capture's intrinsics in the captures' convention (pixel centres at integer + 0.5).
pub fn capture_intrinsics(pinhole: &Lens) -> geom::Intrinsics {
    geom::Intrinsics {
        fx: pinhole.fx,
        fy: pinhole.fy,
        cx: pinhole.cx + 0.5,
        cy: pinhole.cy + 0.5,
        skew: 0.0,
    }
}

/// What a capture shows, which sets the rule for its region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subject {
    /// An object the cameras look at: the region is what they frame there.
    Object,
    /// A scene: the region is the part of the table three quarters of the cameras see.
    Scene,
}

/// The region (ball: centre, radius) a capture's `scale_mat` maps to the unit sphere, and the rule that
/// gave it: the box `region` (`x0,y0,z0,x1,y1,z1`, metres) when given, else by `subject`'s rule
/// (`calib::region`).
pub fn capture_region(
    region: Option<&[f64]>,
    subject: Subject,
    images: &[SourceImage],
    scale: f64,
    size: (u32, u32),
    name: &str,
) -> Result<((Vec3<f64>, f64), &'static str)> {
    if let Some(r) = region {
        let (lo, hi) = (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]));
        if !(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z) {
            fail!(
                Settings,
                "--region {r:?}: x0,y0,z0,x1,y1,z1 with each upper bound above its lower one"
            );
        }
        return Ok((((lo + hi) * 0.5, (hi - lo).norm() * 0.5), "--region"));
    }
    let cameras: Vec<geom::Camera<f64>> = images
        .iter()
        .map(|i| geom::Camera {
            k: capture_intrinsics(&capture_pinhole(&i.lens, scale)),
            world_to_cam: i.pose,
            width: size.0,
            height: size.1,
        })
        .collect();
    let found = match subject {
        Subject::Object => {
            let looking: Vec<Looking> = cameras.iter().map(Looking::from_camera).collect();
            looked_at_region(&looking).map(|r| {
                (
                    r,
                    "the point nearest every optical axis; the median radius the cameras frame there",
                )
            })
        }
        Subject::Scene => seen_table_region(&cameras).map(|r| {
            (
                r,
                "a scene: the part of the board's plane at least three quarters of the cameras see, on the plane",
            )
        }),
    };
    found.ok_or_else(|| err!(Input, "{name}: its cameras do not look at the board, so its region cannot be found: give --region x0,y0,z0,x1,y1,z1"))
}

/// Writes the capture into `dir` (`image/NNN.png` in `images`' order, `cameras_sphere.npz`,
/// `capture.json`): every raw image undistorted to `size` through its lens's pinhole at `scale`.
pub fn write_capture(
    dir: &Path,
    images: &[SourceImage],
    size: (u32, u32),
    scale: f64,
    region: (Vec3<f64>, f64),
    info: &CaptureInfo,
    task: &Task,
) -> Result<()> {
    let digits = images.len().to_string().len().max(3);
    let results: Vec<Result<()>> = images
        .par_iter()
        .enumerate()
        .map(|(k, i)| {
            let raw = pganeus_io::read_image(&i.path)?;
            let out = undistort_image(&raw, &i.lens, &capture_pinhole(&i.lens, scale), size.0, size.1);
            pganeus_io::write_png(&dir.join("image").join(format!("{k:0digits$}.png")), &out)?;
            task.inc(1);
            Ok(())
        })
        .collect();
    results.into_iter().collect::<Result<()>>()?;
    let (centre, radius) = region;
    let mats: Vec<CameraMats> = images
        .iter()
        .map(|i| CameraMats {
            world_mat: geom::Camera {
                k: capture_intrinsics(&capture_pinhole(&i.lens, scale)),
                world_to_cam: i.pose,
                width: size.0,
                height: size.1,
            }
            .world_mat(),
            scale_mat: [
                [radius, 0.0, 0.0, centre.x],
                [0.0, radius, 0.0, centre.y],
                [0.0, 0.0, radius, centre.z],
                [0.0, 0.0, 0.0, 1.0],
            ],
        })
        .collect();
    pganeus_io::write_cameras_npz(&dir.join("cameras_sphere.npz"), &mats)?;
    pganeus_io::write_capture_info(&dir.join("capture.json"), info)?;
    Ok(())
}
