//! `transforms.json` (nerfstudio, instant-ngp, NeRF's Blender scenes): camera-to-world matrices in OpenGL's
//! camera axes (x right, y up, z backward), a lens shared by every frame or given per frame.
//!
//! Principal points in these files put the image's top-left corner at (0, 0), as COLMAP does (nerfstudio
//! and instant-ngp copy COLMAP's); the lens here puts the top-left pixel's centre there: half a pixel apart.

use std::path::{Path, PathBuf};

use geom::{Mat3, Pose, Quat, Vec3};
use serde_json::Value;

use crate::lens::Lens;
use crate::reconstruction::{Reconstruction, RegisteredImage};

/// Why a transforms.json could not be read: the file and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{}: {msg}", path.display())]
pub struct TransformsError {
    pub path: PathBuf,
    pub msg: String,
}

/// A transforms.json read: the reconstruction (image names as the file gives them, relative to the file's
/// folder), and the sparse point file it names, if any (nerfstudio's `ply_file_path`).
pub struct Transforms {
    pub reconstruction: Reconstruction,
    pub points_file: Option<PathBuf>,
}

/// Reads a transforms.json. Image sizes the file does not give are asked of `image_size` (given the path of
/// a frame's image) — NeRF's Blender scenes give only `camera_angle_x`.
pub fn read_transforms(
    path: &Path,
    image_size: &dyn Fn(&Path) -> Option<(u32, u32)>,
) -> Result<Transforms, TransformsError> {
    let fail = |msg: String| TransformsError {
        path: path.to_path_buf(),
        msg,
    };
    let text = std::fs::read_to_string(path).map_err(|e| fail(e.to_string()))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| fail(format!("not JSON: {e}")))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let frames = v["frames"]
        .as_array()
        .ok_or_else(|| fail("no `frames` list: not a transforms.json".into()))?;
    if frames.is_empty() {
        return Err(fail("`frames` is empty".into()));
    }
    let mut images = Vec::with_capacity(frames.len());
    for (i, frame) in frames.iter().enumerate() {
        let at = |msg: String| fail(format!("frames[{i}]: {msg}"));
        let name = frame["file_path"].as_str().ok_or_else(|| at("no `file_path`".into()))?;
        let name = resolve_image(base, name);
        // A frame's own value, else the file's.
        let get = |key: &str| frame.get(key).or_else(|| v.get(key)).and_then(Value::as_f64);
        let model = frame
            .get("camera_model")
            .or_else(|| v.get("camera_model"))
            .and_then(Value::as_str)
            .unwrap_or("OPENCV");
        if model != "OPENCV" && model != "PINHOLE" && model != "SIMPLE_PINHOLE" {
            return Err(at(format!("camera_model {model}: pganeus reads OPENCV (and pinhole) lenses; undistort fisheye or equirectangular images first")));
        }
        let (width, height) = match (get("w"), get("h")) {
            (Some(w), Some(h)) => (w as u32, h as u32),
            _ => image_size(&base.join(&name)).ok_or_else(|| {
                at(format!(
                    "no `w` and `h`, and the image {name} cannot be read for its size"
                ))
            })?,
        };
        let fx = get("fl_x")
            .or_else(|| get("camera_angle_x").map(|a| 0.5 * width as f64 / (0.5 * a).tan()))
            .ok_or_else(|| at("no focal length (`fl_x` or `camera_angle_x`)".into()))?;
        let fy = get("fl_y")
            .or_else(|| get("camera_angle_y").map(|a| 0.5 * height as f64 / (0.5 * a).tan()))
            .unwrap_or(fx);
        let cx = get("cx").unwrap_or(0.5 * width as f64);
        let cy = get("cy").unwrap_or(0.5 * height as f64);
        let k = |key: &str| get(key).unwrap_or(0.0);
        if k("k4") != 0.0 {
            return Err(at(
                "k4 is set: a fisheye lens; pganeus reads OPENCV lenses (k1 k2 p1 p2 k3)".into(),
            ));
        }
        let lens = Lens {
            fx,
            fy,
            cx: cx - 0.5,
            cy: cy - 0.5,
            distortion: [k("k1"), k("k2"), k("p1"), k("p2"), k("k3")],
        };
        let m = &frame["transform_matrix"];
        let row = |r: usize| -> Option<[f64; 4]> {
            let a = m.get(r)?.as_array()?;
            Some([
                a.first()?.as_f64()?,
                a.get(1)?.as_f64()?,
                a.get(2)?.as_f64()?,
                a.get(3)?.as_f64()?,
            ])
        };
        let (r0, r1, r2) = match (row(0), row(1), row(2)) {
            (Some(a), Some(b), Some(c)) => (a, b, c),
            _ => return Err(at("`transform_matrix` is not a 4x4 (or 3x4) matrix of numbers".into())),
        };
        let pose = pose_from_opengl_c2w([r0, r1, r2])
            .ok_or_else(|| at("`transform_matrix`'s 3x3 block is not a rotation (scaled or sheared axes)".into()))?;
        if !(fx > 0.0 && fy > 0.0 && width > 0 && height > 0) {
            return Err(at(format!("focal length {fx} x {fy} for a {width}x{height} image")));
        }
        images.push(RegisteredImage {
            name,
            width,
            height,
            lens,
            pose,
        });
    }
    let points_file = v["ply_file_path"].as_str().map(|p| base.join(p));
    Ok(Transforms {
        reconstruction: Reconstruction {
            images,
            points: Vec::new(),
        },
        points_file,
    })
}

/// A frame's image path relative to the file's folder: NeRF's Blender scenes leave out the extension.
fn resolve_image(base: &Path, name: &str) -> String {
    let name = name.strip_prefix("./").unwrap_or(name);
    if Path::new(name).extension().is_none() {
        for ext in ["png", "jpg", "jpeg", "PNG", "JPG"] {
            let with = format!("{name}.{ext}");
            if base.join(&with).exists() {
                return with;
            }
        }
    }
    name.to_string()
}

/// OpenGL camera-to-world (rows of the 3x4 block) → OpenCV world-to-camera; `None` when the block is not a
/// rotation.
fn pose_from_opengl_c2w(m: [[f64; 4]; 3]) -> Option<Pose<f64>> {
    // OpenCV's camera axes are OpenGL's with y and z flipped: the 2nd and 3rd columns negated.
    let r = Mat3::from_rows([
        [m[0][0], -m[0][1], -m[0][2]],
        [m[1][0], -m[1][1], -m[1][2]],
        [m[2][0], -m[2][1], -m[2][2]],
    ]);
    let rtr = r.transpose().mul_mat(&r);
    let off: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| (rtr.m[i][j] - if i == j { 1.0 } else { 0.0 }).abs())
        .fold(0.0, f64::max);
    if off > 1e-3 || r.det() < 0.0 {
        return None;
    }
    let c2w = Pose::new(Quat::from_mat(&r).unit(), Vec3::new(m[0][3], m[1][3], m[2][3]));
    Some(c2w.inverse())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_opengl_camera_looking_down_is_an_opencv_camera_looking_down() {
        // A camera 2 above the origin looking straight down -z (OpenGL: it looks along its -z, so its axes
        // are the world's), image up along +y.
        let pose = pose_from_opengl_c2w([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 2.0]]).unwrap();
        // The origin is 2 in front of it, on its axis.
        let p = pose.transform_point(Vec3::new(0.0, 0.0, 0.0));
        assert!((p - Vec3::new(0.0, 0.0, 2.0)).norm() < 1e-12, "{p:?}");
        // A point at +y in the world is up in the image: negative OpenCV y.
        assert!(pose.transform_point(Vec3::new(0.0, 1.0, 0.0)).y < 0.0);
        assert!(pose_from_opengl_c2w([[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 2.0]]).is_none());
    }

    #[test]
    fn a_file_is_read_with_half_pixel_centres_and_refused_for_fisheye() {
        let dir = testkit::scratch_dir("calib", "transforms");
        let path = dir.join("transforms.json");
        std::fs::write(&path, r#"{"camera_model": "OPENCV", "fl_x": 500, "fl_y": 502, "cx": 320.5, "cy": 240, "w": 640, "h": 480, "k1": -0.1, "p2": 0.001,
            "frames": [{"file_path": "images/a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]},
                       {"file_path": "images/b.png", "fl_x": 400, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]}"#).unwrap();
        let t = read_transforms(&path, &|_| None).unwrap();
        let r = &t.reconstruction;
        assert_eq!(r.images.len(), 2);
        assert_eq!(r.images[0].lens.cx, 320.0);
        assert_eq!(r.images[0].lens.cy, 239.5);
        assert_eq!(r.images[0].lens.distortion, [-0.1, 0.0, 0.0, 0.001, 0.0]);
        assert_eq!(r.images[1].lens.fx, 400.0);
        assert_eq!(r.images[1].lens.fy, 502.0);
        std::fs::write(&path, r#"{"camera_model": "OPENCV_FISHEYE", "fl_x": 500, "w": 640, "h": 480, "frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2]]}]}"#).unwrap();
        let e = read_transforms(&path, &|_| None).err().unwrap().to_string();
        assert!(e.contains("transforms.json") && e.contains("OPENCV_FISHEYE"), "{e}");
        // Blender's scenes: an angle, no size (asked of the image).
        std::fs::write(&path, r#"{"camera_angle_x": 0.6911112070083618, "frames": [{"file_path": "./train/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]}]}"#).unwrap();
        let t = read_transforms(&path, &|_| Some((800, 800))).unwrap();
        let l = t.reconstruction.images[0].lens;
        assert!((l.fx - 1111.111).abs() < 0.01, "{}", l.fx);
        assert_eq!(t.reconstruction.images[0].name, "train/r_0");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
