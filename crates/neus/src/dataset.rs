//! A capture as training data: images and masks in memory, cameras in the
//! unit sphere where the field lives (`p_unit = scale_mat⁻¹ p_world`), rays.

use geom::{Camera, Vec3};
use pganeus_io::{open_capture, CaptureIndex, IoError};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error(transparent)]
    Io(#[from] IoError),
    #[error("{path}: {msg}")]
    Invalid { path: PathBuf, msg: String },
}

/// One view: its pixels and its camera in unit-sphere coordinates.
#[derive(Clone, Debug)]
pub struct View {
    pub name: String,
    /// RGB in [0, 1], row-major.
    pub rgb: Vec<[f32; 3]>,
    /// 1 = object, 0 = not; absent when the capture has no masks.
    pub mask: Option<Vec<f32>>,
    /// The camera with its pose expressed in unit-sphere coordinates.
    pub camera: Camera<f64>,
}

/// A loaded capture.
pub struct Dataset {
    pub dir: PathBuf,
    pub width: u32,
    pub height: u32,
    pub views: Vec<View>,
    /// Unit sphere → world: `p_world = centre + radius · p_unit`.
    pub centre: Vec3<f64>,
    pub radius: f64,
    /// What `capture.json` says the capture shows, if it says.
    pub subject: Option<pganeus_io::CaptureSubject>,
}

/// A ray in unit coordinates.
#[derive(Clone, Copy, Debug)]
pub struct UnitRay {
    pub origin: [f32; 3],
    pub dir: [f32; 3],
}

impl Dataset {
    /// Load and check a capture (NeuS layout) before any training starts.
    pub fn load(dir: &Path) -> Result<Self, DatasetError> {
        let index = open_capture(dir)?;
        Self::from_index(&index)
    }

    fn from_index(index: &CaptureIndex) -> Result<Self, DatasetError> {
        let invalid = |path: &Path, msg: String| DatasetError::Invalid {
            path: path.to_path_buf(),
            msg,
        };
        let npz = index.dir.join("cameras_sphere.npz");
        let s = &index.cameras[0].scale_mat;
        let radius = s[0][0];
        let uniform = (s[1][1] - radius).abs() < 1e-9 * radius.abs().max(1.0)
            && (s[2][2] - radius).abs() < 1e-9 * radius.abs().max(1.0)
            && [s[0][1], s[0][2], s[1][0], s[1][2], s[2][0], s[2][1]]
                .iter()
                .all(|v| v.abs() < 1e-9)
            && s[3] == [0.0, 0.0, 0.0, 1.0];
        if !(uniform && radius > 0.0) {
            return Err(invalid(
                &npz,
                format!("scale_mat_0 must be a uniform scale plus translation, got {s:?}"),
            ));
        }
        let centre = Vec3::new(s[0][3], s[1][3], s[2][3]);
        let mut views = Vec::with_capacity(index.images.len());
        for (i, img_path) in index.images.iter().enumerate() {
            if index.cameras[i].scale_mat != *s {
                return Err(invalid(
                    &npz,
                    format!("scale_mat_{i} differs from scale_mat_0 (one region per capture)"),
                ));
            }
            let cam = Camera::from_world_mat(&index.cameras[i].world_mat, index.width, index.height)
                .map_err(|e| invalid(&npz, format!("world_mat_{i}: {e}")))?;
            let unit = cam.in_unit_frame(centre, radius);
            let img = pganeus_io::read_image(img_path)?.to_rgb();
            let rgb = img
                .data
                .chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]].map(|v| v as f32 / 255.0))
                .collect();
            let mask = match &index.masks {
                None => None,
                Some(m) => {
                    let g = pganeus_io::read_image(&m[i])?.to_gray();
                    Some(g.data.iter().map(|&v| if v > 127 { 1.0 } else { 0.0 }).collect())
                }
            };
            let name = img_path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            views.push(View {
                name,
                rgb,
                mask,
                camera: unit,
            });
        }
        Ok(Self {
            dir: index.dir.clone(),
            width: index.width,
            height: index.height,
            views,
            centre,
            radius,
            subject: index.info.as_ref().and_then(|i| i.subject),
        })
    }

    /// The ray through pixel coordinates `(u, v)` of view `i`, in unit coordinates.
    pub fn ray(&self, i: usize, u: f64, v: f64) -> UnitRay {
        let r = self.views[i].camera.ray(u, v);
        UnitRay {
            origin: r.origin.to_array().map(|x| x as f32),
            dir: r.dir.to_array().map(|x| x as f32),
        }
    }

    pub fn has_masks(&self) -> bool {
        self.views.first().is_some_and(|v| v.mask.is_some())
    }

    /// The names of the views whose mask marks no pixel (none without masks).
    pub fn empty_masks(&self) -> Vec<&str> {
        self.views
            .iter()
            .filter(|v| v.mask.as_ref().is_some_and(|m| m.iter().all(|&x| x == 0.0)))
            .map(|v| v.name.as_str())
            .collect()
    }
}
