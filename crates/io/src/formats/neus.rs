//! The capture folder of docs/formats.md ("A capture"), laid out as in NeuS
//! (Wang et al. 2021) so that NeuS data loads as is:
//!
//! ```text
//! <capture>/
//!   image/000.png 001.png ...   PNG or JPEG, all the same size; sorted by file name (time, for a video)
//!   mask/000.png  001.png ...   optional; the same names, or as many in the same order (NeuS pairs by
//!                               order: DTU's image/000000.png goes with mask/000.png); white (>127) = the object
//!   mask_<name>/000.png ...     optional extra masks (e.g. one per body), same rules
//!   cameras_sphere.npz          world_mat_i and scale_mat_i per image i (float64, 4x4)
//!   capture.json                optional: {"kind": "static" | "video", "fps": 30.0, "shutter": 0.008, "subject": "scene" | "object"}
//! ```
//!
//! [`open_capture`] lists and checks a capture without decoding any pixels;
//! the images are then read with [`read_image`](crate::read_image).

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use super::image_file::{is_image_file, read_image_size};
use super::npz::{read_npz, write_npz, NpyArray};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};

/// Folder of the images, inside a capture.
pub const IMAGE_DIR: &str = "image";
/// Folder of the (optional) object masks, inside a capture.
pub const MASK_DIR: &str = "mask";
/// Prefix of the folders of extra masks: `mask_<name>/`.
pub const EXTRA_MASK_PREFIX: &str = "mask_";
/// The cameras of a capture.
pub const CAMERAS_FILE: &str = "cameras_sphere.npz";
/// The (optional) description of a capture.
pub const CAPTURE_INFO_FILE: &str = "capture.json";

/// What a capture is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CaptureKind {
    /// Multi-view images of a scene that does not move.
    Static,
    /// A monocular video from one camera that does not move; image order is time.
    Video,
}

/// What a static capture shows (optional in `capture.json`), which decides how a field trained on it starts
/// and what its masks mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CaptureSubject {
    /// One object; masks, if any, mark the object.
    #[default]
    Object,
    /// The static scene: board, obstacles and whatever lies beyond (table, room, backdrop); masks, if any,
    /// mark what is *not* scene.
    Scene,
}

impl CaptureSubject {
    pub fn name(self) -> &'static str {
        match self {
            Self::Object => "object",
            Self::Scene => "scene",
        }
    }
}

/// `capture.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaptureInfo {
    /// Static multi-view images or a video.
    pub kind: CaptureKind,
    /// What a static capture shows; absent: an object when the capture has masks, a scene otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subject: Option<CaptureSubject>,
    /// Frames per second (> 0), for a video.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// How long the shutter is open in each frame of a video, seconds (a moving body blurs over it);
    /// absent: not known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shutter: Option<f64>,
    /// Keys not listed above, kept as they were.
    #[serde(flatten)]
    pub extra: Map<String, Value>,
}

/// The matrices of one image's camera, as NeuS stores them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraMats {
    /// `[[K, 0], [0, 1]] @ W2C`: intrinsics times the 4x4 world-to-camera
    /// matrix (OpenCV axes), row-major (`world_mat[row][col]`).
    pub world_mat: [[f64; 4]; 4],
    /// Maps the unit sphere of the neural field to the world:
    /// `p_world = scale_mat @ p_unit`. The same for every image of a capture.
    pub scale_mat: [[f64; 4]; 4],
}

/// A capture folder, listed and checked by [`open_capture`].
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureIndex {
    /// The capture folder.
    pub dir: PathBuf,
    /// `image/*.png`, sorted by file name.
    pub images: Vec<PathBuf>,
    /// `mask/*.png`, one per image in the same order, if the capture has masks.
    pub masks: Option<Vec<PathBuf>>,
    /// Extra mask folders `mask_<name>/`, sorted by name: (`name`, one mask per image).
    pub extra_masks: Vec<(String, Vec<PathBuf>)>,
    /// One camera per image, from `cameras_sphere.npz`.
    pub cameras: Vec<CameraMats>,
    /// `capture.json`, if present.
    pub info: Option<CaptureInfo>,
    /// Width of every image, pixels.
    pub width: u32,
    /// Height of every image, pixels.
    pub height: u32,
}

impl CaptureIndex {
    /// Number of images.
    pub fn len(&self) -> usize {
        self.images.len()
    }

    /// `true` if the capture has no image (never, for one from [`open_capture`]).
    pub fn is_empty(&self) -> bool {
        self.images.is_empty()
    }
}

/// Reads and checks a `capture.json` (`fps`, if present, finite and > 0; `shutter` 0 or more and at most a frame).
pub fn read_capture_info(path: &Path) -> Result<CaptureInfo> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        cause: source,
    })?;
    let info: CaptureInfo = serde_json::from_slice(&bytes).map_err(|source| IoError::Json {
        path: path.to_path_buf(),
        cause: source,
    })?;
    check_info(&info, path)?;
    Ok(info)
}

/// Checks `info` and writes it as pretty JSON to `path` (a `capture.json`), atomically.
pub fn write_capture_info(path: &Path, info: &CaptureInfo) -> Result<()> {
    check_info(info, path)?;
    let mut bytes = serde_json::to_vec_pretty(info).map_err(|source| IoError::Json {
        path: path.to_path_buf(),
        cause: source,
    })?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

fn check_info(info: &CaptureInfo, path: &Path) -> Result<()> {
    let invalid = |field: &str, msg: String| IoError::Invalid {
        path: path.to_path_buf(),
        field: field.to_string(),
        msg,
    };
    if let Some(fps) = info.fps {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(invalid("fps", format!("must be finite and > 0, is {fps}")));
        }
    }
    if let Some(shutter) = info.shutter {
        if !(shutter.is_finite() && shutter >= 0.0) {
            return Err(invalid("shutter", format!("must be 0 or more seconds, is {shutter}")));
        }
        if let Some(fps) = info.fps.filter(|&fps| shutter * fps > 1.0) {
            return Err(invalid(
                "shutter",
                format!("{shutter} s is longer than a frame at {fps} fps"),
            ));
        }
    }
    Ok(())
}

const IDENTITY: [[f64; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// Writes the cameras of a capture as NeuS does, atomically: for each image
/// `i`, `world_mat_i`, `scale_mat_i` and their inverses `world_mat_inv_i`,
/// `scale_mat_inv_i`, plus `camera_mat_i` and `camera_mat_inv_i`, which NeuS
/// datasets carry but no loader uses; here they are the identity. All are
/// float64 of shape (4, 4), so `np.load(path)['world_mat_%d' % i]` works.
///
/// Every value must be finite and both matrices invertible; otherwise nothing
/// is written and the error names the matrix.
pub fn write_cameras_npz(path: &Path, cameras: &[CameraMats]) -> Result<()> {
    let invalid = |field: String, msg: String| IoError::Invalid {
        path: path.to_path_buf(),
        field,
        msg,
    };
    let mut arrays: Vec<(String, NpyArray)> = Vec::with_capacity(cameras.len() * 6);
    for (i, cam) in cameras.iter().enumerate() {
        let mut named = vec![
            (format!("camera_mat_{i}"), IDENTITY),
            (format!("camera_mat_inv_{i}"), IDENTITY),
        ];
        for (name, m) in [("world_mat", &cam.world_mat), ("scale_mat", &cam.scale_mat)] {
            let key = format!("{name}_{i}");
            if let Some((r, c)) = first_non_finite(m) {
                return Err(invalid(
                    format!("{key}[{r}][{c}]"),
                    format!("is not finite ({})", m[r][c]),
                ));
            }
            let inv = invert4(m).ok_or_else(|| invalid(key.clone(), "is singular".to_string()))?;
            named.push((key, *m));
            named.push((format!("{name}_inv_{i}"), inv));
        }
        arrays.extend(named.into_iter().map(|(k, m)| (k, mat_array(&m))));
    }
    let refs: Vec<(&str, &NpyArray)> = arrays.iter().map(|(k, a)| (k.as_str(), a)).collect();
    write_npz(path, &refs)
}

/// Reads `world_mat_i` and `scale_mat_i` for `i` in `0..count` from a
/// `cameras_sphere.npz`; any numeric dtype is accepted. Other entries are
/// ignored. A missing or bad entry (absent, not of shape (4, 4), holding a
/// value that is not finite) is an [`IoError::Capture`] naming it; a file
/// that cannot be read or is not a valid NPZ is [`IoError::Open`] or [`IoError::Npz`].
pub fn read_cameras_npz(path: &Path, count: usize) -> Result<Vec<CameraMats>> {
    let entries: BTreeMap<String, NpyArray> = read_npz(path)?.into_iter().collect();
    let err = |msg: String| IoError::Capture {
        path: path.to_path_buf(),
        msg,
    };
    let get = |key: String| -> Result<[[f64; 4]; 4]> {
        let a = entries
            .get(&key)
            .ok_or_else(|| err(format!("no entry {key} (the capture has {count} images)")))?;
        if a.shape != [4, 4] {
            let dims: Vec<String> = a.shape.iter().map(|d| d.to_string()).collect();
            return Err(err(format!("{key} has shape ({}), expected (4, 4)", dims.join(", "))));
        }
        let v = a.as_f64();
        let m: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|c| v[4 * r + c]));
        if let Some((r, c)) = first_non_finite(&m) {
            return Err(err(format!("{key}[{r}][{c}] is not finite ({})", m[r][c])));
        }
        Ok(m)
    };
    (0..count)
        .map(|i| {
            Ok(CameraMats {
                world_mat: get(format!("world_mat_{i}"))?,
                scale_mat: get(format!("scale_mat_{i}"))?,
            })
        })
        .collect()
}

fn mat_array(m: &[[f64; 4]; 4]) -> NpyArray {
    NpyArray::f64(vec![4, 4], m.iter().flatten().copied().collect())
}

fn first_non_finite(m: &[[f64; 4]; 4]) -> Option<(usize, usize)> {
    (0..16).map(|k| (k / 4, k % 4)).find(|&(r, c)| !m[r][c].is_finite())
}

/// Inverse by Gauss-Jordan elimination with partial pivoting; `None` if singular.
fn invert4(m: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut a = *m;
    let mut inv = IDENTITY;
    for col in 0..4 {
        let pivot = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col] == 0.0 {
            return None;
        }
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let p = a[col][col];
        for k in 0..4 {
            a[col][k] /= p;
            inv[col][k] /= p;
        }
        for row in 0..4 {
            if row != col {
                let f = a[row][col];
                for k in 0..4 {
                    a[row][k] -= f * a[col][k];
                    inv[row][k] -= f * inv[col][k];
                }
            }
        }
    }
    inv.iter().flatten().all(|x| x.is_finite()).then_some(inv)
}

/// Lists and checks a capture folder (see the module doc), decoding no pixels.
///
/// Checks: `image/` holds at least one PNG or JPEG; every image has the size
/// of the first (read from the file's header only); `mask/` and each
/// `mask_<name>/`, if present, hold one image per image of the capture, each
/// of its size, paired by file stem, or by sorted order when the names differ
/// and the counts agree; `cameras_sphere.npz` exists and has `world_mat_i`
/// and `scale_mat_i` (4x4, finite) for every image; `capture.json`, if
/// present, is valid. Other files (hidden files, notes) are ignored.
///
/// Every error is an [`IoError::Capture`] whose path is the offending file or folder.
pub fn open_capture(dir: &Path) -> Result<CaptureIndex> {
    if !dir.is_dir() {
        return Err(capture_err(dir, "not a capture: no such folder"));
    }
    let image_dir = dir.join(IMAGE_DIR);
    if !image_dir.is_dir() {
        return Err(capture_err(&image_dir, "missing: a capture keeps its images in image/"));
    }
    let images = list_images(&image_dir)?;
    if images.is_empty() {
        return Err(capture_err(&image_dir, "no images (PNG or JPEG)"));
    }

    let mut sizes = Vec::with_capacity(images.len());
    for img in &images {
        let size = read_image_size(img).map_err(to_capture)?;
        if size != sizes.first().copied().unwrap_or(size) {
            return Err(capture_err(
                img,
                &format!(
                    "is {}x{} but {} is {}x{}; every image of a capture must have the same size",
                    size.0,
                    size.1,
                    images[0].display(),
                    sizes[0].0,
                    sizes[0].1
                ),
            ));
        }
        sizes.push(size);
    }
    let (width, height) = sizes[0];

    let mask_dir = dir.join(MASK_DIR);
    let masks = if mask_dir.is_dir() {
        Some(match_masks(&images, &mask_dir, (width, height))?)
    } else {
        None
    };
    let mut extra_masks = Vec::new();
    for (name, folder) in list_extra_mask_dirs(dir)? {
        let paths = match_masks(&images, &folder, (width, height))?;
        extra_masks.push((name, paths));
    }

    let npz = dir.join(CAMERAS_FILE);
    if !npz.is_file() {
        return Err(capture_err(&npz, "missing: every capture needs cameras_sphere.npz"));
    }
    let cameras = read_cameras_npz(&npz, images.len()).map_err(to_capture)?;

    let info_path = dir.join(CAPTURE_INFO_FILE);
    let info = if info_path.exists() {
        Some(read_capture_info(&info_path).map_err(to_capture)?)
    } else {
        None
    };

    Ok(CaptureIndex {
        dir: dir.to_path_buf(),
        images,
        masks,
        extra_masks,
        cameras,
        info,
        width,
        height,
    })
}

fn capture_err(path: &Path, msg: &str) -> IoError {
    IoError::Capture {
        path: path.to_path_buf(),
        msg: msg.to_string(),
    }
}

/// Turns any error about a file of the capture into an [`IoError::Capture`] about that file.
fn to_capture(e: IoError) -> IoError {
    match e {
        IoError::Capture { .. } => e,
        e => IoError::Capture {
            path: e.path().to_path_buf(),
            msg: e.detail(),
        },
    }
}

fn read_dir_sorted(folder: &Path) -> Result<Vec<PathBuf>> {
    let io_err = |e: std::io::Error| capture_err(folder, &format!("cannot list: {e}"));
    let mut paths = Vec::new();
    for entry in std::fs::read_dir(folder).map_err(io_err)? {
        paths.push(entry.map_err(io_err)?.path());
    }
    // Sort by file name, the order of docs/formats.md (time, for a video).
    paths.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    Ok(paths)
}

/// The PNG and JPEG files of a folder, sorted by file name.
fn list_images(folder: &Path) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    for path in read_dir_sorted(folder)? {
        let hidden = path.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.'));
        if hidden || !path.is_file() {
            continue;
        }
        if is_image_file(&path) {
            found.push(path);
        }
    }
    Ok(found)
}

/// The `mask_<name>/` folders of a capture, sorted by name.
fn list_extra_mask_dirs(dir: &Path) -> Result<Vec<(String, PathBuf)>> {
    let mut found = Vec::new();
    for path in read_dir_sorted(dir)? {
        let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
            continue;
        };
        if let Some(suffix) = name.strip_prefix(EXTRA_MASK_PREFIX) {
            if !suffix.is_empty() && path.is_dir() {
                found.push((suffix.to_string(), path));
            }
        }
    }
    Ok(found)
}

/// One mask per image from `folder`, each the image size: matched by file stem when every image has a mask
/// of its name, else by sorted order when the counts agree (as NeuS pairs them: DTU's `image/000000.png`
/// goes with `mask/000.png`).
fn match_masks(images: &[PathBuf], folder: &Path, size: (u32, u32)) -> Result<Vec<PathBuf>> {
    let stem = |p: &Path| p.file_stem().map(OsString::from).unwrap_or_default();
    let listed = list_images(folder)?;
    let mut by_stem: BTreeMap<OsString, PathBuf> = listed.iter().map(|p| (stem(p), p.clone())).collect();
    let named = images.iter().all(|img| by_stem.contains_key(&stem(img)));
    let masks: Vec<PathBuf> = if !named && listed.len() == images.len() {
        tracing::info!(
            "{}: masks paired with images by sorted order (their names differ, as in NeuS's DTU folders)",
            folder.display()
        );
        listed
    } else {
        let mut masks = Vec::with_capacity(images.len());
        for img in images {
            let Some(mask) = by_stem.remove(&stem(img)) else {
                let expected = folder.join(img.file_name().unwrap_or_default());
                return Err(capture_err(
                    &expected,
                    &format!(
                        "missing: no mask for image {} ({} masks for {} images, so they cannot be paired by order either)",
                        img.display(),
                        listed.len(),
                        images.len()
                    ),
                ));
            };
            masks.push(mask);
        }
        if let Some((s, mask)) = by_stem.into_iter().next() {
            let image_dir = images[0].parent().unwrap_or(Path::new(""));
            let mut file = s;
            file.push(".png");
            let expected = image_dir.join(file);
            return Err(capture_err(
                &mask,
                &format!("mask has no image (expected {})", expected.display()),
            ));
        }
        masks
    };
    for (img, mask) in images.iter().zip(&masks) {
        let mask_size = read_image_size(mask).map_err(to_capture)?;
        if mask_size != size {
            return Err(capture_err(
                mask,
                &format!(
                    "mask is {}x{} but its image {} is {}x{}",
                    mask_size.0,
                    mask_size.1,
                    img.display(),
                    size.0,
                    size.1
                ),
            ));
        }
    }
    Ok(masks)
}
