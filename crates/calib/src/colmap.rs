//! COLMAP sparse models (text and binary): cameras, registered images with their world-to-camera poses,
//! and the sparse points: what importing a COLMAP reconstruction starts from.
//!
//! COLMAP's pixel convention puts the top-left pixel's centre at (0.5, 0.5); OpenCV's (and the lens here)
//! at (0, 0): a principal point read from COLMAP is moved by half a pixel.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use geom::{Pose, Quat, Vec3};

use crate::lens::Lens;
use crate::reconstruction::{Reconstruction, RegisteredImage};

/// One COLMAP camera: its size and lens (OpenCV's convention).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    pub width: u32,
    pub height: u32,
    pub lens: Lens,
    /// COLMAP's model name.
    pub model: String,
}

/// One registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    pub name: String,
    pub camera_id: u32,
    /// World to camera.
    pub pose: Pose<f64>,
    /// Its 2-D points: pixel (OpenCV's convention) and the 3-D point's id, if any.
    pub points: Vec<([f64; 2], Option<u64>)>,
}

/// A sparse model.
#[derive(Clone, Debug, Default)]
pub struct ColmapModel {
    pub cameras: BTreeMap<u32, ColmapCamera>,
    pub images: Vec<ColmapImage>,
    /// Point id → position (world).
    pub points: BTreeMap<u64, Vec3<f64>>,
}

impl ColmapModel {
    /// Its registered images and points (`dir`, the model's folder, names it in errors).
    pub fn reconstruction(&self, dir: &Path) -> Result<Reconstruction, ColmapError> {
        let images = self
            .images
            .iter()
            .map(|i| {
                let c = self.cameras.get(&i.camera_id).ok_or_else(|| {
                    error(
                        dir,
                        format!(
                            "image {} names camera {}, which the model does not have",
                            i.name, i.camera_id
                        ),
                    )
                })?;
                Ok(RegisteredImage {
                    name: i.name.clone(),
                    width: c.width,
                    height: c.height,
                    lens: c.lens,
                    pose: i.pose,
                })
            })
            .collect::<Result<_, ColmapError>>()?;
        Ok(Reconstruction {
            images,
            points: self.points.values().copied().collect(),
        })
    }
}

/// Why a model could not be read: the file and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{}: {msg}", path.display())]
pub struct ColmapError {
    pub path: PathBuf,
    pub msg: String,
}

fn error(path: &Path, msg: impl Into<String>) -> ColmapError {
    ColmapError {
        path: path.to_path_buf(),
        msg: msg.into(),
    }
}

fn fail<T>(path: &Path, msg: impl Into<String>) -> Result<T, ColmapError> {
    Err(error(path, msg))
}

/// The lens of a COLMAP camera model and its parameters; `None` for models the OpenCV lens cannot hold.
fn lens_of(model: &str, p: &[f64]) -> Option<Lens> {
    let half = 0.5;
    let (fx, fy, cx, cy, d) = match (model, p.len()) {
        ("SIMPLE_PINHOLE", 3) => (p[0], p[0], p[1], p[2], [0.0; 5]),
        ("PINHOLE", 4) => (p[0], p[1], p[2], p[3], [0.0; 5]),
        ("SIMPLE_RADIAL", 4) => (p[0], p[0], p[1], p[2], [p[3], 0.0, 0.0, 0.0, 0.0]),
        ("RADIAL", 5) => (p[0], p[0], p[1], p[2], [p[3], p[4], 0.0, 0.0, 0.0]),
        ("OPENCV", 8) => (p[0], p[1], p[2], p[3], [p[4], p[5], p[6], p[7], 0.0]),
        ("FULL_OPENCV", 12) if p[9..].iter().all(|v| *v == 0.0) => {
            (p[0], p[1], p[2], p[3], [p[4], p[5], p[6], p[7], p[8]])
        }
        _ => return None,
    };
    Some(Lens {
        fx,
        fy,
        cx: cx - half,
        cy: cy - half,
        distortion: d,
    })
}

/// What a model with another camera can do.
const READ_MODELS: &str = "pganeus reads SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV without k4-k6 (re-run COLMAP's image_undistorter, or pick one of those)";

const MODELS: [(&str, usize); 11] = [
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
    ("FOV", 5),
    ("SIMPLE_RADIAL_FISHEYE", 4),
    ("RADIAL_FISHEYE", 5),
    ("THIN_PRISM_FISHEYE", 12),
];

/// Reads a model folder: `cameras.txt`, `images.txt`, `points3D.txt`, or the `.bin` files.
pub fn read_model(dir: &Path) -> Result<ColmapModel, ColmapError> {
    if dir.join("cameras.bin").exists() {
        read_binary(dir)
    } else if dir.join("cameras.txt").exists() {
        read_text(dir)
    } else {
        fail(
            dir,
            "no cameras.txt or cameras.bin: not a COLMAP sparse model folder (sparse/0)",
        )
    }
}

fn read_text(dir: &Path) -> Result<ColmapModel, ColmapError> {
    let mut model = ColmapModel::default();
    let path = dir.join("cameras.txt");
    let text = std::fs::read_to_string(&path).map_err(|e| error(&path, e.to_string()))?;
    for (n, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'))
    {
        let w: Vec<&str> = line.split_whitespace().collect();
        let at = |m: String| fail::<()>(&path, format!("line {}: {m}", n + 1));
        if w.len() < 4 {
            at("CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]".into())?;
        }
        let num = |s: &str| {
            s.parse::<f64>()
                .map_err(|_| error(&path, format!("line {}: `{s}` is not a number", n + 1)))
        };
        let params: Vec<f64> = w[4..].iter().map(|s| num(s)).collect::<Result<_, _>>()?;
        let lens = lens_of(w[1], &params).ok_or_else(|| {
            error(
                &path,
                format!(
                    "line {}: camera model {} with {} parameters: {READ_MODELS}",
                    n + 1,
                    w[1],
                    params.len()
                ),
            )
        })?;
        let id = num(w[0])? as u32;
        model.cameras.insert(
            id,
            ColmapCamera {
                width: num(w[2])? as u32,
                height: num(w[3])? as u32,
                lens,
                model: w[1].to_string(),
            },
        );
    }
    let path = dir.join("images.txt");
    let text = std::fs::read_to_string(&path).map_err(|e| error(&path, e.to_string()))?;
    let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
    let mut i = 0;
    while i < lines.len() {
        let header = lines[i];
        if header.trim().is_empty() {
            i += 1;
            continue;
        }
        let w: Vec<&str> = header.split_whitespace().collect();
        if w.len() < 10 {
            return fail(
                &path,
                format!("`{header}`: IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"),
            );
        }
        let num = |s: &str| {
            s.parse::<f64>()
                .map_err(|_| error(&path, format!("`{s}` is not a number")))
        };
        let q = Quat::new(num(w[1])?, num(w[2])?, num(w[3])?, num(w[4])?).unit();
        let t = Vec3::new(num(w[5])?, num(w[6])?, num(w[7])?);
        let camera_id = num(w[8])? as u32;
        let name = w[9..].join(" ");
        let mut points = Vec::new();
        if let Some(p) = lines.get(i + 1) {
            let v: Vec<&str> = p.split_whitespace().collect();
            for c in v.chunks(3).filter(|c| c.len() == 3) {
                let id = c[2].parse::<i64>().unwrap_or(-1);
                points.push(([num(c[0])? - 0.5, num(c[1])? - 0.5], (id >= 0).then_some(id as u64)));
            }
        }
        model.images.push(ColmapImage {
            name,
            camera_id,
            pose: Pose::new(q, t),
            points,
        });
        i += 2;
    }
    let path = dir.join("points3D.txt");
    if let Ok(text) = std::fs::read_to_string(&path) {
        for line in text.lines().filter(|l| !l.trim().is_empty() && !l.starts_with('#')) {
            let w: Vec<&str> = line.split_whitespace().collect();
            if w.len() >= 4 {
                if let (Ok(id), Ok(x), Ok(y), Ok(z)) = (w[0].parse::<u64>(), w[1].parse(), w[2].parse(), w[3].parse()) {
                    model.points.insert(id, Vec3::new(x, y, z));
                }
            }
        }
    }
    Ok(model)
}

/// A little-endian reader over a file's bytes that names the file when it runs out.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
    path: &'a Path,
}

impl<'a> Bytes<'a> {
    fn new(data: &'a [u8], path: &'a Path) -> Self {
        Bytes { data, at: 0, path }
    }

    fn take(&mut self, n: usize) -> Result<&[u8], ColmapError> {
        if self.at + n > self.data.len() {
            return fail(self.path, format!("truncated at byte {}", self.at));
        }
        let s = &self.data[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u64(&mut self) -> Result<u64, ColmapError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn i64(&mut self) -> Result<i64, ColmapError> {
        Ok(i64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn u32(&mut self) -> Result<u32, ColmapError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn i32(&mut self) -> Result<i32, ColmapError> {
        Ok(i32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn f64(&mut self) -> Result<f64, ColmapError> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn name(&mut self) -> Result<String, ColmapError> {
        let start = self.at;
        while self.take(1)?[0] != 0 {}
        Ok(String::from_utf8_lossy(&self.data[start..self.at - 1]).into_owned())
    }
}

/// A model file's bytes, the error naming it.
fn read_file(path: &Path) -> Result<Vec<u8>, ColmapError> {
    std::fs::read(path).map_err(|e| error(path, e.to_string()))
}

fn read_binary(dir: &Path) -> Result<ColmapModel, ColmapError> {
    let mut model = ColmapModel::default();
    let path = dir.join("cameras.bin");
    let data = read_file(&path)?;
    let mut b = Bytes::new(&data, &path);
    for _ in 0..b.u64()? {
        let id = b.u32()?;
        let model_id = b.i32()?;
        let (name, n) = *MODELS
            .get(model_id as usize)
            .ok_or_else(|| error(&path, format!("unknown camera model id {model_id}")))?;
        let (width, height) = (b.u64()? as u32, b.u64()? as u32);
        let params: Vec<f64> = (0..n).map(|_| b.f64()).collect::<Result<_, _>>()?;
        let lens =
            lens_of(name, &params).ok_or_else(|| error(&path, format!("camera {id}: model {name}: {READ_MODELS}")))?;
        model.cameras.insert(
            id,
            ColmapCamera {
                width,
                height,
                lens,
                model: name.into(),
            },
        );
    }
    let path = dir.join("images.bin");
    let data = read_file(&path)?;
    let mut b = Bytes::new(&data, &path);
    for _ in 0..b.u64()? {
        let _id = b.u32()?;
        let q = Quat::new(b.f64()?, b.f64()?, b.f64()?, b.f64()?).unit();
        let t = Vec3::new(b.f64()?, b.f64()?, b.f64()?);
        let camera_id = b.u32()?;
        let name = b.name()?;
        let mut points = Vec::new();
        for _ in 0..b.u64()? {
            let (x, y, id) = (b.f64()?, b.f64()?, b.i64()?);
            points.push(([x - 0.5, y - 0.5], (id >= 0).then_some(id as u64)));
        }
        model.images.push(ColmapImage {
            name,
            camera_id,
            pose: Pose::new(q, t),
            points,
        });
    }
    let path = dir.join("points3D.bin");
    if let Ok(data) = std::fs::read(&path) {
        let mut b = Bytes::new(&data, &path);
        for _ in 0..b.u64()? {
            let id = b.u64()?;
            let p = Vec3::new(b.f64()?, b.f64()?, b.f64()?);
            b.take(3)?;
            b.f64()?;
            let track = b.u64()?;
            b.take(8 * track as usize)?;
            model.points.insert(id, p);
        }
    }
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_text_model_is_read_with_opencvs_pixel_centres() {
        let dir = testkit::scratch_dir("calib", "colmap_text");
        std::fs::write(dir.join("cameras.txt"), "# Camera list\n1 OPENCV 640 480 500 502 320.5 240.5 -0.1 0.01 0.001 0.0005\n2 SIMPLE_RADIAL 640 480 510 320 240 -0.05\n").unwrap();
        std::fs::write(dir.join("images.txt"), "# Image list\n1 1 0 0 0 0.1 0.2 0.3 1 a.jpg\n100.5 200.5 7 50 60 -1\n2 0.7071068 0.7071068 0 0 0 0 1 2 b c.jpg\n\n").unwrap();
        std::fs::write(dir.join("points3D.txt"), "7 0.1 0.2 0.3 255 0 0 0.5 1 0\n").unwrap();
        let m = read_model(&dir).unwrap();
        assert_eq!(m.cameras.len(), 2);
        assert!((m.cameras[&1].lens.cx - 320.0).abs() < 1e-12, "half a pixel");
        assert_eq!(m.cameras[&2].lens.distortion[0], -0.05);
        assert_eq!(m.images.len(), 2);
        assert_eq!(m.images[1].name, "b c.jpg");
        assert_eq!(m.images[0].points[0], ([100.0, 200.0], Some(7)));
        assert_eq!(m.images[0].points[1].1, None);
        assert_eq!(m.points.len(), 1);
        std::fs::write(dir.join("cameras.txt"), "1 FOV 640 480 500 320 240 0.9\n").unwrap();
        let e = read_model(&dir).unwrap_err().to_string();
        assert!(e.contains("cameras.txt") && e.contains("FOV"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
