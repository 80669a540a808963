//! `pganeus import`: a raw session as a person with a camera brings it (FORMATS.md "A raw session":
//! `board.toml`, `background/`, `<object>_a/` and `<object>_b/`, one folder per video, plain images) → the
//! data `run`, `train` and `fit` read: every folder calibrated on the board ([`crate::calibrate`], its
//! captures in the NeuS layout) and `session.json` naming the scene, the objects and the videos.
//!
//! A folder's role is its name: `background` is the scene, `calibration` close-ups for the lens only,
//! `<name>_a` and `<name>_b` an object in its two poses, any other folder of images a video from a fixed
//! camera. A video file (`.mp4`, `.mov`, …) is cut into frames by `ffmpeg` when it is installed.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::calibrate::{run as calibrate, CalibrateArgs, CalibrateOutcome};
use crate::error::{fail, Context};
use crate::{note, Observer, Result};

/// `pganeus import` arguments.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus import session --out data
  pganeus import session --board prints/board.toml --out data --width 320")
)]
pub struct ImportSessionArgs {
    /// The raw session: `board.toml`, `background/`, `<object>_a/`, `<object>_b/` and a folder (or a video
    /// file) per video.
    pub session: PathBuf,
    /// The printed board (default: `SESSION/board.toml`).
    #[cfg_attr(feature = "clap", arg(long))]
    pub board: Option<PathBuf>,
    /// The data folder to write: one capture per folder, `calibration.json` and `session.json`.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Width of the captures' images, pixels (the height keeps the aspect); default: the raw width.
    #[cfg_attr(feature = "clap", arg(long))]
    pub width: Option<u32>,
    /// Frames per second of the videos (a video file's own rate when it is read through ffmpeg).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 30.0))]
    pub fps: f64,
    /// Hold a known lens: the calibration.json of an earlier session with the same camera and zoom.
    #[cfg_attr(feature = "clap", arg(long))]
    pub intrinsics: Option<PathBuf>,
    /// Solve for k3 as well (wide-angle lenses).
    #[cfg_attr(feature = "clap", arg(long))]
    pub k3: bool,
    /// Replace `--out` if it exists (the old folder is kept until the new one is complete).
    #[cfg_attr(feature = "clap", arg(long))]
    pub force: bool,
}

impl ImportSessionArgs {
    /// The flags' defaults for `session` written to `out`.
    pub fn new(session: impl Into<PathBuf>, out: impl Into<PathBuf>) -> Self {
        ImportSessionArgs {
            session: session.into(),
            board: None,
            out: out.into(),
            width: None,
            fps: 30.0,
            intrinsics: None,
            k3: false,
            force: false,
        }
    }
}

/// `session.json`: what a session holds, by capture name (folders of the data folder).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// The raw session it was imported from.
    pub source: PathBuf,
    /// The board file it was calibrated on.
    pub board: PathBuf,
    /// The scene's capture (the board and obstacles without the bodies).
    pub scene: String,
    /// Each object and its two captures (resting in two poses).
    pub objects: Vec<SessionObject>,
    /// The videos' captures.
    pub videos: Vec<String>,
    /// The bodies a video shows, by video, where it does not show every object (a user's edit: `import`
    /// cannot tell).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub video_bodies: std::collections::BTreeMap<String, Vec<String>>,
}

/// One object of a session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SessionObject {
    pub name: String,
    /// `<name>_a` and `<name>_b`.
    pub captures: [String; 2],
}

/// The file a data folder's session is described in.
pub const SESSION_FILE: &str = "session.json";

/// Reads `DATA/session.json`.
pub fn read_session(data: &Path) -> Result<Session> {
    let path = data.join(SESSION_FILE);
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("cannot read {} (made by `pganeus import`)", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a session file", path.display()))
}

/// Video files `import` cuts into frames through ffmpeg.
const VIDEO_EXTENSIONS: [&str; 7] = ["mp4", "mov", "avi", "mkv", "webm", "m4v", "mts"];

/// The session's folders by role.
#[derive(Debug, Default)]
struct Layout {
    scene: Option<PathBuf>,
    lens_only: Option<PathBuf>,
    objects: Vec<(String, [PathBuf; 2])>,
    videos: Vec<PathBuf>,
    video_files: Vec<PathBuf>,
}

/// What `import` made: the session and how its calibration went.
pub struct Imported {
    pub session: Session,
    pub calibration: CalibrateOutcome,
}

/// `pganeus import`.
pub fn run(a: &ImportSessionArgs, observer: &dyn Observer) -> Result<Imported> {
    let board = a.board.clone().unwrap_or_else(|| a.session.join("board.toml"));
    if !board.is_file() {
        fail!(
            Input,
            "{}: no board file (the printed board's board.toml; give --board when it lies elsewhere)",
            board.display()
        );
    }
    if a.out.exists() && !a.force {
        fail!(
            OutputTaken,
            "{} exists: import writes a new data folder (choose another --out, or --force to replace it)",
            a.out.display()
        );
    }
    let mut layout = layout(&a.session)?;
    // Video files become folders of frames beside the output, then captures like the others.
    let frames_root = a.out.with_file_name(format!(
        ".{}.frames",
        a.out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    ));
    // The frames cut from video files are gone after, whatever happens.
    struct Scratch(PathBuf);
    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
    let _scratch = Scratch(frames_root.clone());
    for file in std::mem::take(&mut layout.video_files) {
        layout.videos.push(extract_frames(&file, &frames_root)?);
    }
    let Some(scene) = layout.scene.clone() else {
        fail!(
            Input,
            "{}: no background/ folder (photos of the scene without the moving bodies, from around it)",
            a.session.display()
        );
    };
    if layout.objects.is_empty() {
        fail!(
            Input,
            "{}: no object captures: photograph each object resting on the board in two poses, into \
             <name>_a/ and <name>_b/",
            a.session.display()
        );
    }
    if layout.videos.is_empty() {
        tracing::warn!(
            "{}: no videos: the scene and the objects are imported, there is nothing to fit",
            a.session.display()
        );
    }
    let mut c = CalibrateArgs::new(
        layout
            .objects
            .iter()
            .flat_map(|(_, pair)| pair.iter().cloned())
            .collect(),
        &board,
        &a.out,
    );
    c.scenes = vec![scene.clone()];
    c.videos = layout.videos.clone();
    c.lens_only = layout.lens_only.iter().cloned().collect();
    c.width = a.width;
    c.fps = a.fps;
    c.intrinsics = a.intrinsics.clone();
    c.k3 = a.k3;
    let calibration = calibrate(&c, observer)?;
    let name = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let session = Session {
        source: a.session.clone(),
        board,
        scene: name(&scene),
        objects: layout
            .objects
            .iter()
            .map(|(n, [x, y])| SessionObject {
                name: n.clone(),
                captures: [name(x), name(y)],
            })
            .collect(),
        videos: layout.videos.iter().map(|v| name(v)).collect(),
        video_bodies: Default::default(),
    };
    for v in &session.videos {
        if let Some(why) = still_video(&a.out.join(v))? {
            tracing::warn!("{}: {why}", a.out.join(v).display());
            note(observer, format!("warning: video {v}: {why}"));
        }
    }
    pganeus_io::write_atomic(&a.out.join(SESSION_FILE), &serde_json::to_vec_pretty(&session)?)?;
    note(
        observer,
        format!(
            "imported {}: the scene, {} object(s) ({}), {} video(s) ({}) into {}",
            a.session.display(),
            session.objects.len(),
            session
                .objects
                .iter()
                .map(|o| o.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            session.videos.len(),
            session.videos.join(", "),
            a.out.display()
        ),
    );
    Ok(Imported { session, calibration })
}

/// The session's folders and video files by role; a lone half of an object, a second camera, or a video
/// given twice are refused by name.
fn layout(session: &Path) -> Result<Layout> {
    let entries =
        std::fs::read_dir(session).with_context(|| format!("cannot read the session folder {}", session.display()))?;
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    let mut out = Layout::default();
    let mut halves: Vec<(String, char, PathBuf)> = Vec::new();
    for p in paths {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if name.starts_with('.') {
            continue;
        }
        if p.is_file() {
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            if VIDEO_EXTENSIONS.contains(&ext.as_str()) {
                out.video_files.push(p);
            }
            continue;
        }
        if !p.is_dir() {
            continue;
        }
        let has_images = std::fs::read_dir(&p)
            .with_context(|| format!("cannot read {}", p.display()))?
            .filter_map(|e| e.ok())
            .any(|e| pganeus_io::is_image_file(&e.path()));
        if !has_images {
            tracing::info!("{}: no images, not a capture: left out", p.display());
            continue;
        }
        if p.join("camera.json").exists() {
            fail!(
                Input,
                "{}: a second camera (camera.json) in one session is not supported yet: import the folders \
                 it shot as a session of their own",
                p.join("camera.json").display()
            );
        }
        match name.as_str() {
            "background" => out.scene = Some(p),
            "calibration" => out.lens_only = Some(p),
            _ => match name.rsplit_once('_') {
                Some((object, side @ ("a" | "b"))) if !object.is_empty() => {
                    halves.push((object.to_string(), side.chars().next().unwrap_or('a'), p))
                }
                _ => out.videos.push(p),
            },
        }
    }
    for (object, side, path) in &halves {
        if *side != 'a' {
            continue;
        }
        let Some((_, _, other)) = halves.iter().find(|(o, s, _)| o == object && *s == 'b') else {
            fail!(
                Input,
                "{}: no {object}_b/ beside it: each object is photographed resting in two poses, \
                 {object}_a/ and {object}_b/ (turned over, so that together they see all of it)",
                path.display()
            );
        };
        out.objects.push((object.clone(), [path.clone(), other.clone()]));
    }
    if let Some((object, _, path)) = halves
        .iter()
        .find(|(o, s, _)| *s == 'b' && !out.objects.iter().any(|(n, _)| n == o))
    {
        fail!(
            Input,
            "{}: no {object}_a/ beside it: each object is photographed resting in two poses, {object}_a/ and \
             {object}_b/",
            path.display()
        );
    }
    for file in &out.video_files {
        let stem = file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if out
            .videos
            .iter()
            .any(|v| v.file_name().is_some_and(|n| n.to_string_lossy() == stem))
        {
            fail!(
                Input,
                "{} and the folder {stem}/ are the same video twice: keep one",
                file.display()
            );
        }
    }
    Ok(out)
}

/// Cuts the video `file` into PNG frames in `root/<stem>/` through ffmpeg; without ffmpeg, the error says
/// the command that does it.
fn extract_frames(file: &Path, root: &Path) -> Result<PathBuf> {
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let dir = root.join(&stem);
    let by_hand = format!(
        "ffmpeg -i {} {}/%05d.png",
        file.display(),
        file.with_file_name(&stem).display()
    );
    let available = std::process::Command::new("ffmpeg")
        .arg("-version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !available {
        fail!(
            Input,
            "{}: a video file needs ffmpeg, which is not installed: install it (e.g. `apt install ffmpeg`), or \
             cut the video into frames yourself and import again: {by_hand}",
            file.display()
        );
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let out = std::process::Command::new("ffmpeg")
        .args(["-v", "error", "-i"])
        .arg(file)
        .arg(dir.join("%05d.png"))
        .output()
        .with_context(|| format!("cannot run ffmpeg on {}", file.display()))?;
    if !out.status.success() {
        fail!(
            Input,
            "{}: ffmpeg could not read it: {}",
            file.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(dir)
}

/// Why a video's frames show nothing moving (`None` when something moves): the largest share of pixels
/// any frame changes from the video's per-pixel median, against the share a body of a few hundred pixels
/// covers.
fn still_video(capture: &Path) -> Result<Option<String>> {
    let c = pganeus_io::open_capture(capture)?;
    if c.images.len() < 2 {
        return Ok(Some(format!("{} frame: a video needs at least 2", c.images.len())));
    }
    let frames = c
        .images
        .iter()
        .map(|p| crate::images::reference_frame(p))
        .collect::<Result<Vec<_>>>()?;
    let n = frames[0].len();
    let median: Vec<[f32; 3]> = (0..n)
        .map(|p| {
            std::array::from_fn(|ch| {
                let mut v: Vec<f32> = frames.iter().map(|f| f[p][ch]).collect();
                let mid = v.len() / 2;
                *v.select_nth_unstable_by(mid, f32::total_cmp).1
            })
        })
        .collect();
    let moved = frames
        .iter()
        .map(|f| {
            // The frame at the median's exposure (a camera's drifting auto-exposure moves every pixel).
            let mut ratios: Vec<f32> = f
                .iter()
                .zip(&median)
                .filter(|(_, b)| b[0] + b[1] + b[2] > 0.15)
                .map(|(a, b)| (a[0] + a[1] + a[2]) / (b[0] + b[1] + b[2]))
                .collect();
            let gain = if ratios.is_empty() {
                1.0
            } else {
                let mid = ratios.len() / 2;
                *ratios.select_nth_unstable_by(mid, f32::total_cmp).1
            };
            f.iter()
                .zip(&median)
                .filter(|(a, b)| (0..3).map(|ch| (a[ch] / gain - b[ch]).abs()).sum::<f32>() > STILL_DIFFERENCE)
                .count()
        })
        .max()
        .unwrap_or(0);
    Ok((moved * 10_000 < n * STILL_SHARE_PER_10K).then(|| {
        format!(
            "nothing moves in its {} frames (at most {moved} of {n} pixels change from frame to frame): \
             is the body in view, and did it move?",
            frames.len()
        )
    }))
}

/// A pixel changes where its summed colour moves by more than this from the video's median (noise and a
/// drifting exposure stay well below).
const STILL_DIFFERENCE: f32 = 0.25;

/// A video where no frame changes more than this many pixels in 10,000 shows nothing moving.
const STILL_SHARE_PER_10K: usize = 5;
