//! An imported session scored against the truth `synth --raw` keeps beside its raw footage: the cameras
//! `import` found on the printed board against the ones that rendered the photos (`camera_truth.json` and
//! the truth captures), and the masks the method computed against the true meshes drawn through those
//! computed cameras. What `demo --preset raw` reports and the raw-session tests hold.

use std::path::Path;

use geom::{Camera, Pose, Quat, Vec3};
use serde_json::Value;

use crate::error::{err, Context};
use crate::run_folder::read_json;
use crate::Result;

/// How far the imported cameras are from the truth, over every photo and video frame `import` kept.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraScore {
    /// The lens's focal lengths off the truth, the worse of x and y, percent.
    pub focal_percent: f64,
    /// The principal point off the truth, raw pixels.
    pub principal_px: f64,
    /// Camera centres off the truth, mm: mean and worst.
    pub centre_mm: [f64; 2],
    /// Camera orientations off the truth, degrees: mean and worst.
    pub turn_deg: [f64; 2],
    /// Cameras compared, and photos in the raw folders (the rest left out by `import`).
    pub cameras: usize,
    pub photos: usize,
}

/// One capture's computed masks against the true silhouettes.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskScore {
    pub capture: String,
    pub body: String,
    /// IoU per scored view (a video's frames where the true silhouette covers at least
    /// [`VIDEO_MIN_PIXELS`]), in order, with the view's index.
    pub views: Vec<(usize, f64)>,
}

impl MaskScore {
    pub fn mean(&self) -> f64 {
        self.views.iter().map(|v| v.1).sum::<f64>() / self.views.len().max(1) as f64
    }

    /// The worst view: its index and IoU.
    pub fn worst(&self) -> Option<(usize, f64)> {
        self.views.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

/// A video frame is scored where the body covers at least this many pixels (the bar: a body
/// smaller than that is a few pixels' edge, where one pixel moves the IoU by percents).
pub const VIDEO_MIN_PIXELS: usize = 200;

/// Each camera of a capture folder.
fn capture_cameras(dir: &Path) -> Result<Vec<Camera<f64>>> {
    let index = pganeus_io::open_capture(dir)?;
    index
        .cameras
        .iter()
        .map(|c| {
            Camera::from_world_mat(&c.world_mat, index.width, index.height)
                .map_err(|e| err!(Input, "{}: a camera that is not one: {e}", dir.display()))
        })
        .collect()
}

/// An imported session beside its truth: `calibration.json` and `camera_truth.json`, read once.
struct Sources<'a> {
    imported: &'a Path,
    truth_dir: &'a Path,
    calibration: Value,
    truth: Value,
}

impl<'a> Sources<'a> {
    fn read(imported: &'a Path, truth_dir: &'a Path) -> Result<Self> {
        Ok(Self {
            imported,
            truth_dir,
            calibration: read_json(&imported.join("calibration.json"))?,
            truth: read_json(&truth_dir.join("camera_truth.json"))?,
        })
    }

    /// The captures `import` wrote that the truth knows, by name, each with the photos its raw folder had.
    fn captures(&self) -> Vec<(String, usize)> {
        self.calibration["captures"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|c| c["name"].as_str())
            .filter_map(|name| self.truth_files(name).map(|f| (name.to_string(), f.len())))
            .collect()
    }

    fn truth_files(&self, name: &str) -> Option<&Vec<Value>> {
        self.truth["captures"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|c| c["name"] == name)
            .and_then(|c| c["files"].as_array())
    }

    /// Each camera `import` wrote for capture `name`, in its order, paired with the truth's camera of the
    /// same photo.
    fn paired_cameras(&self, name: &str) -> Result<Vec<(Camera<f64>, Camera<f64>)>> {
        let cal_path = self.imported.join("calibration.json");
        let truth_path = self.truth_dir.join("camera_truth.json");
        let files = self
            .truth_files(name)
            .ok_or_else(|| err!(Input, "{}: no capture {name:?}", truth_path.display()))?;
        let written = self.calibration["captures"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|c| c["name"] == name)
            .and_then(|c| c["images"].as_array())
            .ok_or_else(|| err!(Input, "{}: no images of {name:?}", cal_path.display()))?;
        let found = capture_cameras(&self.imported.join(name))?;
        let true_cams = capture_cameras(&self.truth_dir.join(name))?;
        if written.len() != found.len() {
            crate::error::fail!(
                Input,
                "{}: {name} lists {} images, its capture has {} cameras",
                cal_path.display(),
                written.len(),
                found.len()
            );
        }
        found
            .into_iter()
            .zip(written)
            .map(|(cam, file)| {
                let i = files.iter().position(|f| f == file).ok_or_else(|| {
                    err!(
                        Input,
                        "{}: {name}'s {file} is not in {}",
                        cal_path.display(),
                        truth_path.display()
                    )
                })?;
                let t = true_cams.get(i).ok_or_else(|| {
                    err!(
                        Input,
                        "{}: fewer cameras than files",
                        self.truth_dir.join(name).display()
                    )
                })?;
                Ok((cam, *t))
            })
            .collect()
    }
}

/// The imported session `imported` (import's output: `calibration.json` and a capture per folder) against
/// the truth in `truth_dir` (synth's data folder: `camera_truth.json` and the truth captures).
pub fn cameras(imported: &Path, truth_dir: &Path) -> Result<CameraScore> {
    let src = Sources::read(imported, truth_dir)?;
    let cal_path = imported.join("calibration.json");
    let truth_path = truth_dir.join("camera_truth.json");
    let k = |v: &Value, r: usize, c: usize, file: &Path| {
        v["lens"]["K"][r][c]
            .as_f64()
            .ok_or_else(|| err!(Input, "{}: lens.K is not a 3 × 3 matrix of numbers", file.display()))
    };
    let (cal, truth) = (&src.calibration, &src.truth);
    let mut focal_percent = 0.0f64;
    for i in 0..2 {
        focal_percent =
            focal_percent.max(100.0 * (k(cal, i, i, &cal_path)? / k(truth, i, i, &truth_path)? - 1.0).abs());
    }
    let principal_px = (k(cal, 0, 2, &cal_path)? - k(truth, 0, 2, &truth_path)?)
        .hypot(k(cal, 1, 2, &cal_path)? - k(truth, 1, 2, &truth_path)?);
    let (mut centres, mut turns, mut photos) = (Vec::new(), Vec::new(), 0);
    for (name, n) in src.captures() {
        photos += n;
        for (cam, t) in src.paired_cameras(&name)? {
            centres.push((cam.world_to_cam.inverse().t - t.world_to_cam.inverse().t).norm() * 1000.0);
            turns.push(geom::rotation_distance(cam.world_to_cam.q, t.world_to_cam.q).to_degrees());
        }
    }
    let mean_worst = |v: &[f64]| {
        [
            v.iter().sum::<f64>() / v.len().max(1) as f64,
            v.iter().copied().fold(0.0, f64::max),
        ]
    };
    Ok(CameraScore {
        focal_percent,
        principal_px,
        centre_mm: mean_worst(&centres),
        turn_deg: mean_worst(&turns),
        cameras: centres.len(),
        photos,
    })
}

/// The mask files of a folder of `NNN.png`, sorted.
fn mask_files(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    files.sort();
    Ok(files)
}

/// Computed masks of one capture (`masks`: a folder of one PNG per camera) against `mesh` drawn at
/// `pose_of(view)` through `cams`; views where the true silhouette covers fewer than `min_pixels` are left
/// out.
fn score_masks(
    cams: &[Camera<f64>],
    masks: &Path,
    mesh: &geom::TriMesh,
    pose_of: &dyn Fn(usize) -> Option<Pose<f64>>,
    min_pixels: usize,
) -> Result<Vec<(usize, f64)>> {
    let files = mask_files(masks)?;
    // A fit of the first frames only (`--frames`) writes their masks only.
    if files.len() > cams.len() || files.is_empty() {
        crate::error::fail!(
            Input,
            "{}: {} masks for {} cameras",
            masks.display(),
            files.len(),
            cams.len()
        );
    }
    let mut views = Vec::new();
    for (i, (cam, file)) in cams.iter().zip(&files).enumerate() {
        let Some(pose) = pose_of(i) else { continue };
        let truth = geom::silhouette(cam, mesh, &pose);
        if truth.iter().filter(|&&x| x).count() < min_pixels {
            continue;
        }
        let found = crate::images::read_mask(file)?;
        if found.len() != truth.len() {
            crate::error::fail!(Input, "{}: not the capture's image size", file.display());
        }
        views.push((i, geom::coverage_iou(&found, &truth)));
    }
    Ok(views)
}

fn pose_of(p: &pganeus_io::Pose) -> Pose<f64> {
    Pose::new(Quat::<f64>::cst(p.q), Vec3::cst(p.t))
}

/// The object captures' computed masks (`runs/<capture>/mask/`, as `train` writes them) and each video's
/// (`fits/<video>/mask_<body>/`, as `fit` writes them; videos whose fit read given masks have none and are
/// left out), against the truth in `truth_dir` (synth's data folder): the true mesh at its true pose, drawn
/// through the true camera of the photo with the intrinsics of the image `import` made of it (the pixels
/// the image shows it at; the imported camera's own error would move it by up to a pixel).
pub fn masks(imported: &Path, runs: &Path, fits: &Path, truth_dir: &Path) -> Result<Vec<MaskScore>> {
    let src = Sources::read(imported, truth_dir)?;
    let truth = truth_dir.join("truth.json");
    let t = pganeus_io::read_truth(&truth)?;
    let cameras = |name: &str| -> Result<Vec<Camera<f64>>> {
        Ok(src
            .paired_cameras(name)?
            .into_iter()
            .map(|(found, t)| Camera {
                world_to_cam: t.world_to_cam,
                ..found
            })
            .collect())
    };
    let mut scores = Vec::new();
    for body in &t.bodies {
        for stat in &body.static_captures {
            let masks = runs.join(&stat.capture).join("mask");
            if !masks.is_dir() {
                continue;
            }
            let (mesh, _, _) = crate::surfaces::capture_truth(&truth, &stat.capture)?;
            let views = score_masks(&cameras(&stat.capture)?, &masks, &mesh, &|_| Some(Pose::identity()), 1)?;
            scores.push(MaskScore {
                capture: stat.capture.clone(),
                body: body.name.clone(),
                views,
            });
        }
    }
    for video in &t.videos {
        for vb in &video.bodies {
            let masks = fits.join(&video.capture).join(format!("mask_{}", vb.name));
            if !masks.is_dir() {
                continue;
            }
            let Some(body) = t.bodies.iter().find(|b| b.name == vb.name) else {
                continue;
            };
            let mesh = pganeus_io::read_mesh(&truth_dir.join(&body.mesh))?;
            let views = score_masks(
                &cameras(&video.capture)?,
                &masks,
                &mesh,
                &|i| vb.poses.get(i).map(pose_of),
                VIDEO_MIN_PIXELS,
            )?;
            scores.push(MaskScore {
                capture: video.capture.clone(),
                body: vb.name.clone(),
                views,
            });
        }
    }
    Ok(scores)
}
