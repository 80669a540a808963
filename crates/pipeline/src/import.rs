//! `import-colmap` and `import-transforms`: a reconstruction the user already has (a COLMAP sparse model, a
//! nerfstudio or instant-ngp `transforms.json`) → a capture in the NeuS layout in a metric world with z up.
//!
//! Their worlds are arbitrary (units, axes, origin). With a board file, the board's corners seen in the
//! images are triangulated by the reconstruction's cameras and the similarity onto the printed board is
//! fitted: the board's world, exactly as `calibrate` makes it. Without one, the dominant plane of the sparse
//! points becomes z = 0 and a scale the user gives (a scale bar on the table, or metres per unit) makes it
//! metric. Which of the two was used is logged and written in `import.json`.

use std::path::{Path, PathBuf};

use calib::align::{align_to_board, dominant_plane, Plane};
use calib::calibrate::ViewPoints;
use calib::gray::Gray;
use calib::reconstruction::Reconstruction;
use calib::region::{looked_at_region, Looking};
use calib::Board;
use geom::{Similarity, Vec3};
use pganeus_io::{CaptureInfo, CaptureKind, CaptureSubject};
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::calibrate::Seen;
use crate::capture_writer::{capture_region, capture_size, write_capture, SourceImage, Subject};
use crate::error::{err, fail};
use crate::{note, Observer, Result, Task};

/// What every import takes besides its source.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct ImportArgs {
    /// The capture folder to write (NeuS layout, and import.json).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// The printed board in the images (FORMATS.md "Boards"): the world is the board's, metric.
    #[cfg_attr(feature = "clap", arg(long))]
    pub board: Option<PathBuf>,
    /// Without a board: a known length on the table, `IMG:x,y IMG:x,y LENGTH` (each end a pixel of an image,
    /// both on the table's plane; LENGTH in m, or with mm/cm), as three words or one quoted.
    #[cfg_attr(feature = "clap", arg(long, num_args = 1..=3, value_delimiter = None))]
    pub scale_bar: Option<Vec<String>>,
    /// Without a board: metres per unit of the reconstruction.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scale: Option<f64>,
    /// Width of the capture's images, pixels (the height keeps the aspect); default: the raw width.
    #[cfg_attr(feature = "clap", arg(long))]
    pub width: Option<u32>,
    /// The capture's region, `x0,y0,z0,x1,y1,z1` (metres, the new world): its scale_mat is the ball around it.
    #[cfg_attr(
        feature = "clap",
        arg(long, value_delimiter = ',', num_args = 6, allow_hyphen_values = true)
    )]
    pub region: Option<Vec<f64>>,
    /// The images show the scene (the table where the bodies will move): the region is the part of the
    /// table three quarters of them see, and capture.json says `scene`.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scene: bool,
    /// The fewest board markers an image must show for its board points to be used.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 3))]
    pub min_markers: usize,
}

impl ImportArgs {
    /// The flags' defaults for this output folder.
    pub fn new(out: impl Into<PathBuf>) -> Self {
        ImportArgs {
            out: out.into(),
            board: None,
            scale_bar: None,
            scale: None,
            width: None,
            region: None,
            scene: false,
            min_markers: 3,
        }
    }
}

/// `import-colmap`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus import-colmap colmap/sparse/0 colmap/images --board board.toml --out captures/background --width 320
  pganeus import-colmap sparse/0 images --scale-bar IMG_0003.JPG:812,1404 IMG_0003.JPG:1630,1390 0.30 --out captures/scene")
)]
pub struct ImportColmapArgs {
    /// The sparse model's folder (`sparse/0`): cameras, images and points3D, `.txt` or `.bin`.
    pub model: PathBuf,
    /// The folder of the images the model was made from.
    pub images: PathBuf,
    #[cfg_attr(feature = "clap", command(flatten))]
    pub import: ImportArgs,
}

/// `import-transforms`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus import-transforms nerfstudio/transforms.json --board board.toml --out captures/background --width 320
  pganeus import-transforms data/transforms.json --scale 0.25 --out captures/scene")
)]
pub struct ImportTransformsArgs {
    /// The transforms.json (its images are found relative to its folder).
    pub transforms: PathBuf,
    #[cfg_attr(feature = "clap", command(flatten))]
    pub import: ImportArgs,
}

/// What an import did (also in `import.json`).
#[derive(Clone, Debug)]
pub struct ImportOutcome {
    /// The reconstruction's world → the capture's.
    pub similarity: Similarity,
    /// `board` or `plane`.
    pub alignment: &'static str,
    /// Each image written (as the source names it) and its world-to-camera pose in the capture's world.
    pub cameras: Vec<(String, geom::Pose<f64>)>,
}

/// Imports a COLMAP sparse model.
pub fn import_colmap(a: &ImportColmapArgs, observer: &dyn Observer) -> Result<ImportOutcome> {
    let model = calib::colmap::read_model(&a.model).map_err(|e| crate::Error::Input(e.to_string()))?;
    let rec = model
        .reconstruction(&a.model)
        .map_err(|e| crate::Error::Input(e.to_string()))?;
    let source = json!({"colmap_model": a.model, "images": a.images});
    import(rec, &a.images, &a.model, source, &a.import, observer)
}

/// Imports a transforms.json.
pub fn import_transforms(a: &ImportTransformsArgs, observer: &dyn Observer) -> Result<ImportOutcome> {
    let size = |p: &Path| pganeus_io::read_image_size(p).ok();
    let t = calib::transforms::read_transforms(&a.transforms, &size).map_err(|e| crate::Error::Input(e.to_string()))?;
    let mut rec = t.reconstruction;
    if let Some(ply) = &t.points_file {
        match pganeus_io::read_ply(ply) {
            Ok(cloud) => rec.points = cloud.mesh.vertices.iter().map(|v| Vec3::from_array(*v)).collect(),
            Err(e) => note(
                observer,
                format!("the sparse points it names are not read ({e}); the table's plane cannot come from them"),
            ),
        }
    }
    let base = a.transforms.parent().unwrap_or(Path::new(".")).to_path_buf();
    let source = json!({"transforms": a.transforms});
    import(rec, &base, &a.transforms, source, &a.import, observer)
}

/// The import proper: images found and checked, the world aligned, the capture written.
fn import(
    rec: Reconstruction,
    images_dir: &Path,
    origin: &Path,
    source: Value,
    a: &ImportArgs,
    observer: &dyn Observer,
) -> Result<ImportOutcome> {
    if rec.images.is_empty() {
        fail!(Input, "{}: no registered images", origin.display());
    }
    let paths: Vec<PathBuf> = rec.images.iter().map(|i| images_dir.join(&i.name)).collect();
    for (i, p) in rec.images.iter().zip(&paths) {
        if !p.is_file() {
            fail!(
                Input,
                "{}: the image {} it names is not in {} (give the folder the reconstruction was made from)",
                origin.display(),
                i.name,
                images_dir.display()
            );
        }
        let (w, h) = pganeus_io::read_image_size(p)?;
        if (w, h) != (i.width, i.height) {
            fail!(Input, "{} is {w}x{h} but {} says its camera is {}x{}: was the reconstruction made from these images (not resized ones)?", p.display(), origin.display(), i.width, i.height);
        }
    }
    let first = &rec.images[0];
    if let Some(other) = rec
        .images
        .iter()
        .find(|i| (i.width, i.height) != (first.width, first.height))
    {
        fail!(Input, "{}: {} is {}x{} but {} is {}x{}: a capture's images share one size; import each camera's images separately", origin.display(), other.name, other.width, other.height, first.name, first.width, first.height);
    }
    left_out(&rec, &paths, images_dir, observer);

    let (similarity, alignment) = match &a.board {
        Some(board_file) => {
            if a.scale_bar.is_some() || a.scale.is_some() {
                fail!(
                    Settings,
                    "--board makes the world metric by itself: leave out --scale-bar and --scale"
                );
            }
            let board = Board::read(board_file).map_err(|e| crate::Error::Input(e.to_string()))?;
            board_alignment(&rec, &paths, &board, board_file, a.min_markers, observer)?
        }
        None => plane_alignment(&rec, a, origin, observer)?,
    };
    let moved = rec.transformed(&similarity);
    let below: Vec<&str> = moved
        .images
        .iter()
        .filter(|i| i.pose.inverse().t.z <= 0.0)
        .map(|i| i.name.as_str())
        .collect();
    if !below.is_empty() {
        note(
            observer,
            format!(
                "warning: {} of {} cameras are under the table's plane ({}...): check the alignment",
                below.len(),
                moved.images.len(),
                below[0]
            ),
        );
    }

    let raw = (first.width as usize, first.height as usize);
    let (width, height, scale) = capture_size(raw, a.width.unwrap_or(first.width))?;
    let sources: Vec<SourceImage> = moved
        .images
        .iter()
        .zip(&paths)
        .map(|(i, p)| SourceImage {
            path: p.clone(),
            lens: i.lens,
            pose: i.pose,
        })
        .collect();
    let name = a
        .out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let subject = if a.scene { Subject::Scene } else { Subject::Object };
    let (region, rule) = capture_region(a.region.as_deref(), subject, &sources, scale, (width, height), &name)?;
    let staged = pganeus_io::StagedDir::new(&a.out)?;
    let task = Task::start(observer, "writing the capture", sources.len() as u64);
    let info = CaptureInfo {
        kind: CaptureKind::Static,
        subject: a.scene.then_some(CaptureSubject::Scene),
        fps: None,
        shutter: None,
        extra: Default::default(),
    };
    write_capture(staged.path(), &sources, (width, height), scale, region, &info, &task)?;
    drop(task);
    let report = json!({
        "source": source,
        "alignment": alignment,
        "similarity": {"scale_m_per_unit": similarity.scale, "rotation_wxyz": similarity.rotation.to_array(), "translation_m": similarity.translation.to_array(), "maps": "the reconstruction's world to the capture's: x' = scale * R x + t"},
        "images": moved.images.iter().map(|i| json!({"name": i.name, "centre_m": i.pose.inverse().t.to_array()})).collect::<Vec<_>>(),
        "capture_size": [width, height],
        "region": {"centre": region.0.to_array(), "radius": region.1, "rule": rule},
        "conventions": "World: the board's (origin at the pattern's centre, x right, y toward the print's top, z out of the board) or the table plane's (z = 0, z up, origin under the point the cameras look at), metres. Images numbered in the source's order.",
    });
    let text = serde_json::to_string_pretty(&report)?;
    pganeus_io::write_atomic(&staged.path().join("import.json"), text.as_bytes())?;
    staged.commit()?;
    note(
        observer,
        format!(
            "wrote the capture ({} images, {width}x{height}) to {}",
            sources.len(),
            a.out.display()
        ),
    );
    Ok(ImportOutcome {
        similarity,
        alignment: if a.board.is_some() { "board" } else { "plane" },
        cameras: moved.images.iter().map(|i| (i.name.clone(), i.pose)).collect(),
    })
}

/// Logs the images in the folder the reconstruction did not register (COLMAP often registers only some).
fn left_out(rec: &Reconstruction, paths: &[PathBuf], images_dir: &Path, observer: &dyn Observer) {
    let Ok(entries) = std::fs::read_dir(images_dir) else {
        return;
    };
    let mut missing: Vec<String> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| pganeus_io::is_image_file(p) && !paths.contains(p))
        .map(|p| {
            p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    if missing.is_empty() {
        return;
    }
    missing.sort();
    let shown: Vec<&str> = missing.iter().take(8).map(String::as_str).collect();
    note(
        observer,
        format!(
            "the reconstruction registered {} of the {} images in {}; left out: {}{}",
            rec.images.len(),
            rec.images.len() + missing.len(),
            images_dir.display(),
            shown.join(", "),
            if missing.len() > shown.len() { ", ..." } else { "" }
        ),
    );
}

/// The board's world: its points found in every image (corners refined through the image's lens) and the
/// similarity from their triangulation onto the board.
fn board_alignment(
    rec: &Reconstruction,
    paths: &[PathBuf],
    board: &Board,
    board_file: &Path,
    min_markers: usize,
    observer: &dyn Observer,
) -> Result<(Similarity, Value)> {
    let task = Task::start(observer, "finding the board", paths.len() as u64);
    let found: Vec<Result<(usize, ViewPoints)>> = paths
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let gray = Gray::from_image(&pganeus_io::read_image(p)?);
            let mut seen = Seen::find(&gray, board);
            if seen.markers.len() >= min_markers {
                seen.refine(&gray, board, &rec.images[i].lens);
            }
            task.inc(1);
            Ok((
                i,
                if seen.markers.len() >= min_markers {
                    seen.points
                } else {
                    ViewPoints::default()
                },
            ))
        })
        .collect();
    drop(task);
    let sightings: Vec<(usize, ViewPoints)> = found.into_iter().collect::<Result<_>>()?;
    let a = align_to_board(rec, &sightings, board).map_err(|e| {
        err!(
            Input,
            "{}: {e} (board {}, {} markers needed in an image: --min-markers)",
            board_file.display(),
            board.dictionary.name,
            min_markers
        )
    })?;
    note(
        observer,
        format!(
            "aligned to the board: {} of its points triangulated from {} images ({} left out), {:.2} mm rms and {:.2} mm worst off the printed board; {:.5} m per unit",
            a.points,
            a.images,
            a.rejected,
            1000.0 * a.rms,
            1000.0 * a.worst,
            a.similarity.scale
        ),
    );
    if a.rms > 0.002 {
        note(observer, format!("warning: the board's points are {:.1} mm (rms) off the printed board after the best similarity: the reconstruction's cameras, or the board file, are off", 1000.0 * a.rms));
    }
    Ok((
        a.similarity,
        json!({"method": "board", "board": board_file, "points": a.points, "rejected": a.rejected, "images": a.images, "rms_mm": 1000.0 * a.rms, "worst_mm": 1000.0 * a.worst}),
    ))
}

/// The table's world: the dominant plane of the sparse points at z = 0, the scale the user gave.
fn plane_alignment(
    rec: &Reconstruction,
    a: &ImportArgs,
    origin: &Path,
    observer: &dyn Observer,
) -> Result<(Similarity, Value)> {
    if a.scale_bar.is_none() && a.scale.is_none() {
        fail!(Settings, "{}: its world has no scale; physics needs metres: give --board (a printed board in the images), --scale-bar IMG:x,y IMG:x,y LENGTH (a known length on the table) or --scale (metres per unit)", origin.display());
    }
    if a.scale_bar.is_some() && a.scale.is_some() {
        fail!(Settings, "--scale-bar and --scale both give the scale: keep one");
    }
    let plane = dominant_plane(rec).map_err(|e| err!(Input, "{}: {e}; give --board instead", origin.display()))?;
    let (scale, how) = match (&a.scale_bar, a.scale) {
        (Some(bar), _) => {
            let bar = bar.join(" ");
            let (units, metres) = scale_bar_length(rec, &plane, &bar)?;
            (
                metres / units,
                format!("scale bar {bar}: {units:.5} units for {metres} m"),
            )
        }
        (None, Some(s)) if s.is_finite() && s > 0.0 => (s, format!("--scale {s}")),
        (None, Some(s)) => fail!(Settings, "--scale {s}: metres per unit, above 0"),
        (None, None) => unreachable!("checked above"),
    };
    // Origin under the point the cameras look at; x along the first camera's right.
    let looking: Vec<Looking> = rec
        .images
        .iter()
        .map(|i| Looking::from_pose(&i.pose, 0.5 * i.width as f64 / i.lens.fx))
        .collect();
    let centre = looked_at_region(&looking)
        .map(|r| r.0)
        .unwrap_or_else(|| rec.points.iter().fold(Vec3::zero(), |s, &p| s + p) * (1.0 / rec.points.len() as f64));
    let right = rec.images[0].pose.inverse().transform_vector(Vec3::new(1.0, 0.0, 0.0));
    let similarity = plane.world(centre, right, scale);
    note(
        observer,
        format!(
            "aligned to the dominant plane of the sparse points ({} of {} within 1 %, {:.2} mm rms), {how}; no board: the plane's x and origin are the cameras', not a printed board's",
            plane.inliers,
            rec.points.len(),
            1000.0 * plane.rms * scale
        ),
    );
    Ok((
        similarity,
        json!({"method": "plane", "inliers": plane.inliers, "points": rec.points.len(), "plane_rms_mm": 1000.0 * plane.rms * scale, "scale": how}),
    ))
}

/// The scale bar's length in the reconstruction's units (its ends' rays met with the plane) and in metres.
fn scale_bar_length(rec: &Reconstruction, plane: &Plane, bar: &str) -> Result<(f64, f64)> {
    let bad = |why: &str| {
        err!(Settings, "--scale-bar \"{bar}\": {why}; the form is IMG:x,y IMG:x,y LENGTH (pixels of registered images, LENGTH in m or with mm/cm)")
    };
    let words: Vec<&str> = bar.split_whitespace().collect();
    if words.len() != 3 {
        return Err(bad("three parts needed"));
    }
    let mut ends = Vec::new();
    for w in &words[..2] {
        let (image, xy) = w.rsplit_once(':').ok_or_else(|| bad("an end without IMG:"))?;
        let (x, y) = xy.split_once(',').ok_or_else(|| bad("an end without x,y"))?;
        let (x, y): (f64, f64) = (
            x.parse().map_err(|_| bad("x is not a number"))?,
            y.parse().map_err(|_| bad("y is not a number"))?,
        );
        let reg = rec
            .images
            .iter()
            .find(|i| i.name == image || Path::new(&i.name).file_name().is_some_and(|n| n == image))
            .ok_or_else(|| bad(&format!("{image} is not a registered image")))?;
        let [nx, ny] = reg.lens.undistort(x, y);
        let c2w = reg.pose.inverse();
        let p = plane
            .meet(c2w.t, c2w.transform_vector(Vec3::new(nx, ny, 1.0)))
            .ok_or_else(|| {
                bad(&format!(
                    "the pixel {x},{y} of {image} does not look at the table's plane"
                ))
            })?;
        ends.push(p);
    }
    let text = words[2];
    let (number, unit) = match text.strip_suffix("mm") {
        Some(n) => (n, 0.001),
        None => match text.strip_suffix("cm") {
            Some(n) => (n, 0.01),
            None => (text.strip_suffix('m').unwrap_or(text), 1.0),
        },
    };
    let metres = number.parse::<f64>().map_err(|_| bad("LENGTH is not a number"))? * unit;
    let units = (ends[0] - ends[1]).norm();
    if !(metres > 0.0 && units > 0.0) {
        return Err(bad("the ends are one point, or LENGTH is not above 0"));
    }
    Ok((units, metres))
}
