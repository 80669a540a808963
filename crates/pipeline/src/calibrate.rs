//! `calibrate`: folders of photos and videos of a printed board from one camera → the lens, every view's
//! camera in the board's metric world, and one capture in the NeuS layout per folder (images undistorted
//! and resized, `cameras_sphere.npz`, `capture.json`), with `calibration.json` saying how well it went.

use std::path::{Path, PathBuf};

use calib::calibrate::{calibrate, BoardPose, Calibration, CalibrationSettings, ViewPoints};
use calib::charuco::chessboard_corners;
use calib::detect::{detect_markers, refine_with_lens, DetectedMarker, DetectorSettings};
use calib::gray::Gray;
use calib::{Board, Lens};
use geom::Vec3;
use pganeus_io::{CaptureInfo, CaptureKind, CaptureSubject};
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::capture_writer::{
    capture_intrinsics, capture_pinhole, capture_region, capture_size, write_capture, SourceImage, Subject,
};
use crate::error::{err, fail, Context};
use crate::{note, Observer, Result, Task};

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus calibrate session/background session/toy_a session/toy_b --video session/drop --board session/board.toml --out captures
  pganeus calibrate photos --board board.toml --out captures --width 320
  pganeus calibrate more_photos --board board.toml --out captures2 --intrinsics captures/calibration.json")
)]
pub struct CalibrateArgs {
    /// Folders of photos of a static scene or object (PNG/JPEG, any order): a capture each, `OUT/<folder name>/`.
    pub dirs: Vec<PathBuf>,
    /// The board file (FORMATS.md "Boards").
    #[cfg_attr(feature = "clap", arg(long))]
    pub board: PathBuf,
    /// The output folder: calibration.json and one capture per input folder.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// A folder of photos of the scene (the table where the bodies will move), a capture like the others
    /// whose region is the part of the table three quarters of its photos see, marked a scene in its capture.json
    /// (repeatable).
    #[cfg_attr(feature = "clap", arg(long = "scene"))]
    pub scenes: Vec<PathBuf>,
    /// A folder of a video's frames from a fixed camera, in time order by name (repeatable).
    #[cfg_attr(feature = "clap", arg(long = "video"))]
    pub videos: Vec<PathBuf>,
    /// A folder of photos for the lens only (close-ups of the board filling the frame), not written as a
    /// capture (repeatable).
    #[cfg_attr(feature = "clap", arg(long = "lens-only"))]
    pub lens_only: Vec<PathBuf>,
    /// Width of the captures' images, pixels (the height keeps the aspect); default: the raw width.
    #[cfg_attr(feature = "clap", arg(long))]
    pub width: Option<u32>,
    /// Hold a known lens: the calibration.json of an earlier run with the same camera and zoom.
    #[cfg_attr(feature = "clap", arg(long))]
    pub intrinsics: Option<PathBuf>,
    /// The region of every capture, `x0,y0,z0,x1,y1,z1` (metres, world): its scale_mat is the ball around it.
    #[cfg_attr(
        feature = "clap",
        arg(long, value_delimiter = ',', num_args = 6, allow_hyphen_values = true)
    )]
    pub region: Option<Vec<f64>>,
    /// Solve for k3 as well (wide-angle lenses).
    #[cfg_attr(feature = "clap", arg(long))]
    pub k3: bool,
    /// Frames per second of the videos.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 30.0))]
    pub fps: f64,
    /// The fewest board markers a photo must show to be used.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 3))]
    pub min_markers: usize,
    /// A photo is left out of its capture when its camera's centre is not known to within this (the standard
    /// deviation the scatter of its board points leaves: too little of the board in view), mm.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 2.0))]
    pub camera_tolerance_mm: f64,
}

impl CalibrateArgs {
    /// The flags' defaults for these folders, board and output.
    pub fn new(dirs: Vec<PathBuf>, board: impl Into<PathBuf>, out: impl Into<PathBuf>) -> Self {
        CalibrateArgs {
            dirs,
            board: board.into(),
            out: out.into(),
            scenes: Vec::new(),
            videos: Vec::new(),
            lens_only: Vec::new(),
            width: None,
            intrinsics: None,
            region: None,
            k3: false,
            fps: 30.0,
            min_markers: 3,
            camera_tolerance_mm: 2.0,
        }
    }
}

/// One input folder.
struct Folder {
    name: String,
    dir: PathBuf,
    video: bool,
    /// Photos of the scene (`--scene`).
    scene: bool,
    /// Used for the lens, not written as a capture.
    lens_only: bool,
    images: Vec<PathBuf>,
}

/// What was found of the board in one image.
pub(crate) struct Seen {
    /// The board's points seen: marker corners, and (ChArUco) chessboard corners.
    pub(crate) points: ViewPoints,
    pub(crate) markers: Vec<DetectedMarker>,
    chess: Vec<calib::charuco::ChessCorner>,
    /// Markers of the dictionary that are not on the board.
    foreign_ids: Vec<usize>,
}

impl Seen {
    /// The board's markers (and chessboard corners) in an image.
    pub(crate) fn find(gray: &Gray, board: &Board) -> Seen {
        let markers = detect_markers(gray, board.dictionary, &DetectorSettings::default());
        let (on_board, foreign): (Vec<DetectedMarker>, Vec<DetectedMarker>) =
            markers.into_iter().partition(|m| board.marker(m.id).is_some());
        let chess = chessboard_corners(gray, board, &on_board);
        Seen {
            points: ViewPoints::from_detections(board, &on_board, &chess),
            markers: on_board,
            chess,
            foreign_ids: foreign.iter().map(|m| m.id).collect(),
        }
    }

    /// The markers' corners found again from their edges, undistorted by `lens`.
    pub(crate) fn refine(&mut self, gray: &Gray, board: &Board, lens: &Lens) {
        refine_with_lens(gray, &mut self.markers, board.dictionary, lens);
        self.points = ViewPoints::from_detections(board, &self.markers, &self.chess);
    }
}

/// What `calibrate` found (also in `calibration.json`).
#[derive(Clone, Debug)]
pub struct CalibrateOutcome {
    /// The lens, OpenCV's convention (pixel centres at integers), raw image size.
    pub lens: Lens,
    /// Reprojection error of every kept point, pixels.
    pub rms: f64,
    /// Per capture: its name and the world-to-camera pose of each image written.
    pub cameras: Vec<(String, Vec<geom::Pose<f64>>)>,
}

/// Calibrates and writes the captures (the output folder appears whole, or not at all).
pub fn run(a: &CalibrateArgs, observer: &dyn Observer) -> Result<CalibrateOutcome> {
    let board = Board::read(&a.board).map_err(|e| crate::Error::Input(e.to_string()))?;
    if !(a.fps.is_finite() && a.fps > 0.0) {
        fail!(Settings, "--fps {}: must be above 0", a.fps);
    }
    let folders = list_folders(a)?;
    let size = common_size(&folders)?;
    let known_lens = a.intrinsics.as_deref().map(|p| read_lens(p, size)).transpose()?;

    // Detection in every image.
    let total: usize = folders.iter().map(|f| f.images.len()).sum();
    let written_images: usize = folders.iter().filter(|f| !f.lens_only).map(|f| f.images.len()).sum();
    let task = Task::start(observer, "finding the board", total as u64);
    let mut seen: Vec<Vec<Seen>> = Vec::with_capacity(folders.len());
    for f in &folders {
        let found: Vec<Result<Seen>> = f
            .images
            .par_iter()
            .map(|path| {
                let gray = Gray::from_image(&pganeus_io::read_image(path)?);
                task.inc(1);
                Ok(Seen::find(&gray, &board))
            })
            .collect();
        seen.push(found.into_iter().collect::<Result<_>>()?);
    }
    drop(task);
    check_board_seen(&board, &a.board, &folders, &seen)?;

    let settings = CalibrationSettings {
        known_lens,
        solve_k3: a.k3,
        ..CalibrationSettings::default()
    };
    let everything = |_: &Folder| true;
    // The lens: held (--intrinsics), or from the close-ups alone when there are some (scene photos, the board
    // small in the middle, pull the distortion and the principal point off: on a synth raw session the
    // joint calibration's principal point was 1.45 px off and every camera 0.19 deg, the close-ups' 0.55 px
    // and 0.075 deg), or from every view.
    let lens = match known_lens {
        Some(l) => Some(l),
        None if folders.iter().any(|f| f.lens_only) => {
            let c = two_pass(
                &folders,
                &mut seen,
                &|f: &Folder| f.lens_only,
                &board,
                size,
                &settings,
                a.min_markers,
                observer,
            )?;
            note(
                observer,
                format!(
                    "lens from the close-ups: {}; reprojection rms {:.3} px",
                    lens_text(&c.lens),
                    c.rms
                ),
            );
            Some(c.lens)
        }
        None => None,
    };
    let c = match lens {
        Some(lens) => {
            refine_corners(
                &folders,
                &mut seen,
                &|f: &Folder| !f.lens_only,
                &board,
                &lens,
                a.min_markers,
                observer,
            )?;
            let held = CalibrationSettings {
                known_lens: Some(lens),
                ..settings
            };
            let (views, _, _) = views_of(&folders, &seen, &|f: &Folder| !f.lens_only, a.min_markers, observer)?;
            calibrate(&views, size, &held).map_err(|e| err!(Stage, "calibration failed: {e}"))?
        }
        None => two_pass(
            &folders,
            &mut seen,
            &everything,
            &board,
            size,
            &settings,
            a.min_markers,
            observer,
        )?,
    };
    let (views, owners, mut skipped) = views_of(
        &folders,
        &seen,
        &|f: &Folder| !f.lens_only || lens.is_none(),
        a.min_markers,
        &crate::Quiet,
    )?;
    let photos = owners.iter().filter(|o| o.1.is_some()).count();
    note(
        observer,
        format!(
            "{}; {} views ({photos} photos), reprojection rms {:.3} px",
            lens_text(&c.lens),
            views.len(),
            c.rms
        ),
    );
    if c.rms > 2.0 {
        fail!(Input, "{}: the board's corners are {:.1} px (rms) from where the board file puts them; check that marker_length, marker_separation or square_length, and the kind match the print", a.board.display(), c.rms);
    }
    // Photos whose camera the board leaves uncertain are left out of their captures.
    let limit = a.camera_tolerance_mm / 1000.0;
    let mut uncertain = vec![false; owners.len()];
    for (vi, owner) in owners.iter().enumerate() {
        let sigma = c.centre_sigma[vi];
        // A camera under the table's printed face cannot have seen it: the pose is wrong, whatever its error.
        let behind = !calib::calibrate::sees_printed_face(&c.poses[vi]);
        match owner.1 {
            Some(ii) if sigma > limit || behind => {
                let f = &folders[owner.0];
                let reason = if behind {
                    "its camera comes out under the board, which no photo of its printed face can be: too little of the board in view to fix the pose".to_string()
                } else {
                    format!(
                        "its camera is known only to ±{:.1} mm (--camera-tolerance-mm {}): too little of the board in view",
                        1000.0 * sigma,
                        a.camera_tolerance_mm
                    )
                };
                note(observer, format!("leaving out {}: {reason}", f.images[ii].display()));
                skipped[owner.0].push((file_name(&f.images[ii]), reason));
                uncertain[vi] = true;
            }
            None if sigma > limit => note(
                observer,
                format!(
                    "{}: the video's camera is known only to ±{:.1} mm: more of the board in its view would pin it",
                    folders[owner.0].dir.display(),
                    1000.0 * sigma
                ),
            ),
            _ => {}
        }
    }
    let moved = video_motion(&folders, &seen, &owners, &c, a.min_markers);
    if let Some((name, frames)) = moved.iter().find(|(_, f)| !f.is_empty()) {
        fail!(Input, "{name}: the camera moves during the video (the board's corners are off the video's one camera in frames {}); a video needs a camera that stays still (a tripod), or calibrate its frames as photos", frames.join(", "));
    }

    // The captures.
    let (width, height, scale) = capture_size(size, a.width.unwrap_or(size.0 as u32))?;
    let target = capture_pinhole(&c.lens, scale);
    let staged = pganeus_io::StagedDir::new(&a.out)?;
    let mut report_captures = Vec::new();
    let mut outcome_cameras = Vec::new();
    let writing = Task::start(observer, "writing the captures", written_images as u64);
    for (fi, f) in folders.iter().enumerate() {
        if f.lens_only {
            continue;
        }
        // Each image written: its source and its world-to-camera pose.
        let mut written: Vec<(usize, geom::Pose<f64>)> = Vec::new();
        for (vi, owner) in owners.iter().enumerate() {
            if owner.0 != fi || uncertain[vi] {
                continue;
            }
            let BoardPose { rotation, translation } = c.poses[vi];
            let pose = board.world_to_camera(rotation, translation);
            match owner.1 {
                Some(ii) => written.push((ii, pose)),
                None => written.extend((0..f.images.len()).map(|ii| (ii, pose))),
            }
        }
        if written.is_empty() {
            fail!(Input, "{}: no photo's camera is known to within {} mm (the board too small or too little of it in view): photograph the scene with more of the board in each view, or raise --camera-tolerance-mm", f.dir.display(), a.camera_tolerance_mm);
        }
        let sources: Vec<SourceImage> = written
            .iter()
            .map(|(ii, pose)| SourceImage {
                path: f.images[*ii].clone(),
                lens: c.lens,
                pose: *pose,
            })
            .collect();
        let subject = if f.scene { Subject::Scene } else { Subject::Object };
        let (region, rule) = capture_region(a.region.as_deref(), subject, &sources, scale, (width, height), &f.name)?;
        let info = CaptureInfo {
            kind: if f.video {
                CaptureKind::Video
            } else {
                CaptureKind::Static
            },
            // A static folder given plainly is an object resting on the board: `train` knows it as one
            // (and computes its masks).
            subject: match (f.scene, f.video) {
                (true, _) => Some(CaptureSubject::Scene),
                (false, false) => Some(CaptureSubject::Object),
                (false, true) => None,
            },
            fps: f.video.then_some(a.fps),
            shutter: None,
            extra: Default::default(),
        };
        write_capture(
            &staged.path().join(&f.name),
            &sources,
            (width, height),
            scale,
            region,
            &info,
            &writing,
        )?;
        report_captures.push(capture_report(f, &written, &skipped[fi], &owners, &c, fi, region, rule));
        outcome_cameras.push((f.name.clone(), written.iter().map(|(_, p)| *p).collect()));
    }
    drop(writing);
    let report = json!({
        "board": {"file": a.board, "dictionary": board.dictionary.name, "kind": format!("{:?}", board.spec.kind)},
        "image_size": [size.0, size.1],
        "lens": lens_json(&c.lens),
        "lens_held": known_lens.is_some(),
        "rms_px": c.rms,
        "capture_size": [width, height],
        "capture_K": capture_intrinsics(&target).matrix().m,
        "captures": report_captures,
        "conventions": "lens.K: OpenCV's (pixel centres at integers), raw images; capture_K and cameras_sphere.npz: the captures' (pixel centres at integer + 0.5), undistorted images. World: the board's (origin at the pattern's centre, x right, y toward the print's top, z out of the board), metres.",
    });
    let text = serde_json::to_string_pretty(&report)?;
    pganeus_io::write_atomic(&staged.path().join("calibration.json"), text.as_bytes())?;
    staged.commit()?;
    note(
        observer,
        format!(
            "wrote {} captures and calibration.json to {}",
            folders.len(),
            a.out.display()
        ),
    );
    Ok(CalibrateOutcome {
        lens: c.lens,
        rms: c.rms,
        cameras: outcome_cameras,
    })
}

fn lens_json(l: &Lens) -> Value {
    json!({"K": [[l.fx, 0.0, l.cx], [0.0, l.fy, l.cy], [0.0, 0.0, 1.0]], "distortion": l.distortion, "distortion_names": ["k1", "k2", "p1", "p2", "k3"]})
}

/// The input folders, each with its images sorted by name; names must be distinct.
fn list_folders(a: &CalibrateArgs) -> Result<Vec<Folder>> {
    if a.dirs.is_empty() && a.scenes.is_empty() && a.videos.is_empty() {
        fail!(
            Settings,
            "no folders of images given: pganeus calibrate DIR... --board board.toml --out OUT"
        );
    }
    let mut folders: Vec<Folder> = Vec::new();
    // (folder, video, scene, lens only)
    let inputs = a.dirs.iter().map(|d| (d, false, false, false));
    let inputs = inputs.chain(a.scenes.iter().map(|d| (d, false, true, false)));
    let inputs = inputs.chain(a.videos.iter().map(|d| (d, true, false, false)));
    for (dir, video, scene, lens_only) in inputs.chain(a.lens_only.iter().map(|d| (d, false, false, true))) {
        let entries = std::fs::read_dir(dir).with_context(|| format!("cannot read the folder {}", dir.display()))?;
        let mut images: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| pganeus_io::is_image_file(p))
            .collect();
        images.sort();
        if images.is_empty() {
            fail!(Input, "{}: no PNG or JPEG images in the folder", dir.display());
        }
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "capture".into());
        if let Some(other) = folders.iter().find(|f| f.name == name) {
            fail!(
                Input,
                "{} and {} have the same name; each becomes OUT/{name}/",
                other.dir.display(),
                dir.display()
            );
        }
        folders.push(Folder {
            name,
            dir: dir.clone(),
            video,
            scene,
            lens_only,
            images,
        });
    }
    Ok(folders)
}

/// The one image size of the session (one camera), or an error naming the first image of another size.
fn common_size(folders: &[Folder]) -> Result<(usize, usize)> {
    let first = &folders[0].images[0];
    let (w, h) = pganeus_io::read_image_size(first)?;
    for f in folders {
        for p in &f.images {
            let s = pganeus_io::read_image_size(p)?;
            if s != (w, h) {
                fail!(Input, "{} is {}x{} but {} is {w}x{h}: one camera and zoom make one size; calibrate the other camera's images separately", p.display(), s.0, s.1, first.display());
            }
        }
    }
    Ok((w as usize, h as usize))
}

/// A lens from an earlier run's calibration.json (raw image size must match).
fn read_lens(path: &Path, size: (usize, usize)) -> Result<Lens> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let v: Value = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let bad = || {
        err!(
            Input,
            "{}: not a calibration.json (needs lens.K, lens.distortion and image_size)",
            path.display()
        )
    };
    let k = &v["lens"]["K"];
    let num = |x: &Value| x.as_f64().ok_or_else(bad);
    let d = v["lens"]["distortion"].as_array().ok_or_else(bad)?;
    if d.len() != 5 {
        return Err(bad());
    }
    let lens = Lens {
        fx: num(&k[0][0])?,
        fy: num(&k[1][1])?,
        cx: num(&k[0][2])?,
        cy: num(&k[1][2])?,
        distortion: [num(&d[0])?, num(&d[1])?, num(&d[2])?, num(&d[3])?, num(&d[4])?],
    };
    let held = (num(&v["image_size"][0])? as usize, num(&v["image_size"][1])? as usize);
    if held != size {
        fail!(
            Input,
            "{}: that lens was calibrated on {}x{} images, these are {}x{}",
            path.display(),
            held.0,
            held.1,
            size.0,
            size.1
        );
    }
    Ok(lens)
}

fn lens_text(l: &Lens) -> String {
    let d = l.distortion;
    format!(
        "lens: fx {:.1} fy {:.1} cx {:.1} cy {:.1} px, k1 {:.4} k2 {:.4} p1 {:.5} p2 {:.5} k3 {:.4}",
        l.fx, l.fy, l.cx, l.cy, d[0], d[1], d[2], d[3], d[4]
    )
}

/// A calibration of the views of the folders `which` picks, in two passes: from the corners as detected, then
/// from the markers' corners found again from their edges undistorted by the first pass's lens (a lens bends
/// the sides; the straight sides' corners shortened the focal length by 0.06 % at k1 = -0.26).
#[allow(clippy::too_many_arguments)]
fn two_pass(
    folders: &[Folder],
    seen: &mut [Vec<Seen>],
    which: &(dyn Fn(&Folder) -> bool + Sync),
    board: &Board,
    size: (usize, usize),
    settings: &CalibrationSettings,
    min_markers: usize,
    observer: &dyn Observer,
) -> Result<Calibration> {
    let (views, _, _) = views_of(folders, seen, which, min_markers, observer)?;
    if views.len() < 3 {
        fail!(Input, "{} usable views (photos and videos) of the board; calibrating a lens needs at least 3, better 10 or more from around the board: take more photos, or give --intrinsics", views.len());
    }
    let first = calibrate(&views, size, settings).map_err(|e| err!(Stage, "calibration failed: {e}"))?;
    refine_corners(folders, seen, which, board, &first.lens, min_markers, observer)?;
    let (views, _, _) = views_of(folders, seen, which, min_markers, &crate::Quiet)?;
    calibrate(&views, size, settings).map_err(|e| err!(Stage, "calibration failed: {e}"))
}

/// The markers' corners of the folders `which` picks found again from their edges, undistorted by `lens`.
#[allow(clippy::too_many_arguments)]
fn refine_corners(
    folders: &[Folder],
    seen: &mut [Vec<Seen>],
    which: &(dyn Fn(&Folder) -> bool + Sync),
    board: &Board,
    lens: &Lens,
    min_markers: usize,
    observer: &dyn Observer,
) -> Result<()> {
    let count: usize = folders.iter().filter(|f| which(f)).map(|f| f.images.len()).sum();
    let task = Task::start(observer, "refining the corners with the lens", count as u64);
    for (f, s) in folders.iter().zip(seen.iter_mut()).filter(|(f, _)| which(f)) {
        let refined: Vec<Result<()>> = f
            .images
            .par_iter()
            .zip(s.par_iter_mut())
            .map(|(path, x)| {
                if x.markers.len() >= min_markers {
                    let gray = Gray::from_image(&pganeus_io::read_image(path)?);
                    x.refine(&gray, board, lens);
                }
                task.inc(1);
                Ok(())
            })
            .collect();
        refined.into_iter().collect::<Result<()>>()?;
    }
    Ok(())
}

/// Which view is whose: the folder, and the image for a photo (`None`: a video's frames pooled).
type Owner = (usize, Option<usize>);

/// The calibration's views: each photo with enough markers (the others skipped, with the reason), and each
/// video's frames with enough markers pooled into one view (its one camera).
#[allow(clippy::type_complexity)]
fn views_of(
    folders: &[Folder],
    seen: &[Vec<Seen>],
    which: &(dyn Fn(&Folder) -> bool + Sync),
    min_markers: usize,
    observer: &dyn Observer,
) -> Result<(Vec<ViewPoints>, Vec<Owner>, Vec<Vec<(String, String)>>)> {
    let mut views = Vec::new();
    let mut owners = Vec::new();
    let mut skipped: Vec<Vec<(String, String)>> = vec![Vec::new(); folders.len()];
    for (fi, (f, s)) in folders.iter().zip(seen).enumerate() {
        if !which(f) {
            continue;
        }
        if f.video {
            let mut pooled = ViewPoints::default();
            for frame in s.iter().filter(|x| x.markers.len() >= min_markers) {
                pooled.extend(&frame.points);
            }
            if pooled.board.is_empty() {
                fail!(Input, "{}: no frame shows {min_markers} markers of the board; a video's camera is found from the board it sees", f.dir.display());
            }
            views.push(pooled);
            owners.push((fi, None));
            continue;
        }
        if s.iter().all(|x| x.markers.len() < min_markers) {
            fail!(Input, "{}: none of its {} photos shows {min_markers} markers of the board; a capture's cameras are found from the board it sees: keep the board in view, nearer or larger", f.dir.display(), s.len());
        }
        for (ii, x) in s.iter().enumerate() {
            if x.markers.len() < min_markers {
                let reason = format!("{} board markers seen, {min_markers} needed", x.markers.len());
                note(observer, format!("skipping {}: {reason}", f.images[ii].display()));
                skipped[fi].push((file_name(&f.images[ii]), reason));
                continue;
            }
            views.push(x.points.clone());
            owners.push((fi, Some(ii)));
        }
    }
    Ok((views, owners, skipped))
}

/// An error when the board is nowhere: no marker of the dictionary, or only ids the board does not have.
fn check_board_seen(board: &Board, spec: &Path, folders: &[Folder], seen: &[Vec<Seen>]) -> Result<()> {
    for (f, s) in folders.iter().zip(seen) {
        if s.iter().any(|x| !x.markers.is_empty()) {
            continue;
        }
        let mut foreign: Vec<usize> = s.iter().flat_map(|x| x.foreign_ids.iter().copied()).collect();
        foreign.sort();
        foreign.dedup();
        if let (Some(lo), Some(hi)) = (foreign.first(), foreign.last()) {
            fail!(Input, "{}: markers of {} with ids {lo}..{hi} are in the images, but {} has ids {}..{}: is first_id (or size) in the board file right?", f.dir.display(), board.dictionary.name, spec.display(), board.spec.first_id, board.spec.first_id + board.markers.len() - 1);
        }
        fail!(Input, "{}: no marker of the board in any image; check that {} names the printed board's dictionary ({}), and that the board is in view, sharp and lit", f.dir.display(), spec.display(), board.dictionary.name);
    }
    Ok(())
}

/// Per video: the frames whose board points the video's one camera does not explain (the camera moved).
fn video_motion(
    folders: &[Folder],
    seen: &[Vec<Seen>],
    owners: &[(usize, Option<usize>)],
    c: &Calibration,
    min_markers: usize,
) -> Vec<(String, Vec<String>)> {
    let mut out = Vec::new();
    for (vi, owner) in owners.iter().enumerate() {
        if owner.1.is_some() {
            continue;
        }
        let f = &folders[owner.0];
        let pose = c.poses[vi];
        let mut moved = Vec::new();
        for (ii, x) in seen[owner.0].iter().enumerate() {
            if x.markers.len() < min_markers {
                continue;
            }
            let off = rms_under(&x.points, &c.lens, &pose);
            // The frame's own best camera explains it much better: the camera was elsewhere.
            let own = calibrate(
                std::slice::from_ref(&x.points),
                (1, 1),
                &CalibrationSettings {
                    known_lens: Some(c.lens),
                    ..Default::default()
                },
            )
            .map(|o| o.rms)
            .unwrap_or(off);
            if off > 1.0_f64.max(3.0 * own) {
                moved.push(format!("{} ({off:.1} px)", file_name(&f.images[ii])));
            }
        }
        out.push((f.name.clone(), moved));
    }
    out
}

fn rms_under(points: &ViewPoints, lens: &Lens, pose: &BoardPose) -> f64 {
    let sum: f64 = points
        .board
        .iter()
        .zip(&points.image)
        .map(|(b, i)| {
            let [u, v] = lens.project(pose.rotation.rotate(Vec3::new(b[0], b[1], 0.0)) + pose.translation);
            (u - i[0]).powi(2) + (v - i[1]).powi(2)
        })
        .sum();
    (sum / points.board.len().max(1) as f64).sqrt()
}

#[allow(clippy::too_many_arguments)]
fn capture_report(
    f: &Folder,
    written: &[(usize, geom::Pose<f64>)],
    skipped: &[(String, String)],
    owners: &[(usize, Option<usize>)],
    c: &Calibration,
    fi: usize,
    region: (Vec3<f64>, f64),
    rule: &str,
) -> Value {
    let views: Vec<Value> = owners
        .iter()
        .enumerate()
        .filter(|(_, o)| o.0 == fi)
        .map(|(vi, o)| {
            let file = o.1.map(|ii| file_name(&f.images[ii])).unwrap_or_else(|| format!("{} frames pooled", f.images.len()));
            json!({"source": file, "rms_px": c.view_rms[vi], "centre_sigma_mm": 1000.0 * c.centre_sigma[vi], "points": c.kept[vi].len(), "outliers": c.kept[vi].iter().filter(|k| !**k).count()})
        })
        .collect();
    json!({
        "name": f.name,
        "source": f.dir,
        "kind": if f.video { "video" } else { "static" },
        "subject": match (f.scene, f.video) {
            (true, _) => Some("scene"),
            (false, false) => Some("object"),
            (false, true) => None,
        },
        "images": written.iter().map(|(ii, _)| file_name(&f.images[*ii])).collect::<Vec<_>>(),
        "views": views,
        "skipped": skipped.iter().map(|(file, reason)| json!({"file": file, "reason": reason})).collect::<Vec<_>>(),
        "region": {"centre": region.0.to_array(), "radius": region.1, "rule": rule},
    })
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}
