//! `pganeus masks`: a mask of the moving bodies in every frame of a fixed-camera video, computed from the
//! frames and the trained scene ([`mod@recon::video_masks`]): the scene rendered through the video's camera is
//! the background. Written as a body's `mask_<NAME>/` folder (the layout `fit` reads) with `masks.json`
//! beside it (each frame's area, gain and bar; IoU against masks already in the video, where there are).
//! Given a static object capture instead, its `mask/` from its photos alone ([`crate::object_masks`]).

use crate::error::fail;
use crate::run_folder::checkpoint_of;
use crate::{Context, Observer, Result, Task};
use neus::checkpoint::load_field;
use pganeus_io::Image;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// `pganeus masks` arguments.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus masks data/slide --scene runs/scene --body toy
  pganeus masks data/slide --scene runs/scene --body toy --out inspect/slide_masks
  pganeus masks data/toy_a --out inspect/toy_a_mask")
)]
pub struct MasksArgs {
    /// A fixed-camera video capture (`image/`, `cameras_sphere.npz`), or a static capture of an object
    /// resting on the board (capture.json `"kind": "static"`).
    pub video: PathBuf,
    /// The scene's training run (the board and obstacles without the bodies); a video's masks need it.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scene: Option<PathBuf>,
    /// The body's name: the masks are its `mask_<NAME>/`. One body: the masks hold whatever moves.
    #[cfg_attr(feature = "clap", arg(long, default_value = "body"))]
    pub body: String,
    /// Where to write the masks (default: `VIDEO/mask_<NAME>`, an object capture's `CAPTURE/mask`; refused
    /// where that folder exists).
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: Option<PathBuf>,
}

/// What `masks` measured, per frame (written as `masks.json`).
#[derive(Clone, Debug, Serialize)]
pub struct MasksReport {
    pub video: PathBuf,
    pub out: PathBuf,
    /// Pixels in each frame's mask.
    pub areas: Vec<usize>,
    /// Each frame's exposure against the scene's rendering (an object capture's: against the board the
    /// photos agree on).
    pub gains: Vec<f64>,
    /// Each frame's seed bar (summed colour distance).
    pub bars: Vec<f64>,
    /// Pixels whose background stayed the rendering (no frame showed the scene there).
    pub rendered_background: usize,
    /// Against the video's own `mask_<NAME>/` (or `mask/`), where it has one: each frame's IoU, and the
    /// true mask's area.
    pub against: Option<Against>,
}

/// The computed masks against masks the video already had.
#[derive(Clone, Debug, Serialize)]
pub struct Against {
    pub folder: PathBuf,
    pub iou: Vec<f64>,
    pub areas: Vec<usize>,
}

/// A video's computed masks and what they were computed with.
pub struct ComputedMasks {
    /// One per frame, `width` pixels a row.
    pub masks: Vec<Vec<bool>>,
    pub stats: recon::VideoMaskStats,
    /// The scene rendered through the video's camera.
    pub rendered: Vec<[f32; 3]>,
    pub width: usize,
    /// The frames, as the fit reads them.
    pub frames: Vec<Vec<[f32; 3]>>,
}

/// The masks of a video's moving bodies (the capture `c`, opened from `video`), computed against the scene's
/// field rendered through its one camera.
pub fn compute(
    video: &Path,
    c: &pganeus_io::CaptureIndex,
    scene: &neus::checkpoint::LoadedField,
    observer: &dyn Observer,
) -> Result<ComputedMasks> {
    let camera = crate::cameras::fixed_camera(video, c)?;
    let width = camera.width as usize;
    let pb = Task::start(observer, "reading frames", c.images.len() as u64);
    let frames = c
        .images
        .iter()
        .map(|p| {
            let f = crate::images::reference_frame(p)?;
            if f.len() != width * camera.height as usize {
                fail!(
                    Input,
                    "{}: {} pixels where the camera has {} × {}",
                    p.display(),
                    f.len(),
                    camera.width,
                    camera.height
                );
            }
            pb.inc(1);
            Ok(f)
        })
        .collect::<Result<Vec<_>>>()?;
    pb.finish();
    if frames.len() < 2 {
        fail!(
            Input,
            "{}: masks need at least 2 frames, the video has {}",
            video.display(),
            frames.len()
        );
    }
    let rendered: Vec<[f32; 3]> = crate::cameras::scene_through(scene, &camera)
        .into_iter()
        .map(|r| r.rgb)
        .collect();
    let refs: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
    let (masks, stats) = recon::video_masks(&refs, &rendered, width, &recon::VideoMaskConfig::default());
    Ok(ComputedMasks {
        masks,
        stats,
        rendered,
        width,
        frames,
    })
}

/// A body's look ([`recon::body_masks::Look`]) as `camera` would see it: its reconstruction rendered resting
/// on each of its six sides where the camera's axis meets the board (the side it shows in a video is not
/// known before the fit).
pub fn body_look(object: &neus::ObjectModel, camera: &geom::Camera<f64>) -> recon::body_masks::Look {
    use geom::{Pose, Quat, Vec3};
    use neus::compose::{render_composed, Behind, Composer, Layer};
    let axis = camera.ray(camera.width as f64 / 2.0, camera.height as f64 / 2.0);
    let s = if axis.dir.z < -1e-6 {
        -axis.origin.z / axis.dir.z
    } else {
        0.3
    };
    let (lo, hi) = object.mesh_bounds;
    let reach = (0..3).map(|i| lo[i].abs().max(hi[i].abs())).fold(0.0, f64::max);
    let at = axis.at(s) + Vec3::new(0.0, 0.0, reach);
    let quarter = std::f64::consts::FRAC_PI_2;
    let sides = [
        Quat::identity(),
        Quat::exp(Vec3::new(2.0 * quarter, 0.0, 0.0)),
        Quat::exp(Vec3::new(quarter, 0.0, 0.0)),
        Quat::exp(Vec3::new(-quarter, 0.0, 0.0)),
        Quat::exp(Vec3::new(0.0, quarter, 0.0)),
        Quat::exp(Vec3::new(0.0, -quarter, 0.0)),
    ];
    let mut composer = Composer::default();
    let mut colours = Vec::new();
    for q in sides {
        let pose = Pose::new(q, at);
        let field = object.route(&pose, camera);
        let layer = Layer::object(&field.field, &field.capture_from_body, &pose, 0);
        let img = render_composed(&[layer], 1, Behind::Colour([0.0; 3]), camera, &mut composer);
        colours.extend(
            (0..img.rgb.len())
                .filter(|&p| img.object_opacity[p] > 0.5)
                .map(|p| img.rgb[p]),
        );
    }
    recon::body_masks::Look::of(colours)
}

/// Each body's masks (`[body][frame]`) in a video of several bodies: everything that moves
/// ([`compute`]), split among `objects` by their looks ([`body_look`]) and followed from frame to frame
/// ([`recon::body_masks`]); a body with a first pose in `guesses` is followed from where it draws.
pub fn compute_for_bodies(
    video: &Path,
    c: &pganeus_io::CaptureIndex,
    scene: &neus::checkpoint::LoadedField,
    objects: &[&neus::ObjectModel],
    guesses: &[Option<geom::Pose<f64>>],
    observer: &dyn Observer,
) -> Result<Vec<Vec<Vec<bool>>>> {
    let moving = compute(video, c, scene, observer)?;
    let camera = crate::cameras::fixed_camera(video, c)?;
    let looks: Vec<recon::body_masks::Look> = objects.iter().map(|o| body_look(o, &camera)).collect();
    let refs: Vec<&[[f32; 3]]> = moving.frames.iter().map(|f| f.as_slice()).collect();
    let seeds: Vec<Option<Vec<bool>>> = objects
        .iter()
        .zip(guesses.iter().chain(std::iter::repeat(&None)))
        .map(|(o, g)| g.map(|pose| geom::silhouette(&camera, &o.mesh, &pose)))
        .collect();
    Ok(recon::body_masks::split_by_body(
        &moving.masks,
        &refs,
        moving.width,
        &looks,
        &seeds,
    ))
}

/// Writes `masks` (each `width` pixels a row) into `dir` as `000.png`, `001.png`, … (white inside).
pub fn write_masks(dir: &Path, masks: &[Vec<bool>], width: usize) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let digits = masks.len().saturating_sub(1).to_string().len().max(3);
    for (k, m) in masks.iter().enumerate() {
        let png = Image {
            width: width as u32,
            height: (m.len() / width.max(1)) as u32,
            channels: 1,
            data: m.iter().map(|&v| if v { 255 } else { 0 }).collect(),
        };
        pganeus_io::write_png(&dir.join(format!("{k:0digits$}.png")), &png)?;
    }
    Ok(())
}

/// `pganeus masks`.
pub fn run(a: &MasksArgs, observer: &dyn Observer) -> Result<MasksReport> {
    let c = pganeus_io::open_capture(&a.video)?;
    let is_static = c
        .info
        .as_ref()
        .is_some_and(|i| i.kind == pganeus_io::CaptureKind::Static);
    let default_out = if is_static {
        a.video.join("mask")
    } else {
        a.video.join(format!("mask_{}", a.body))
    };
    let out = a.out.clone().unwrap_or(default_out);
    if a.out.is_none() && out.exists() {
        fail!(
            OutputTaken,
            "{} exists: give --out to write the computed masks elsewhere (the capture's own are compared with them)",
            out.display()
        );
    }
    let beside_out = |suffix: &str| {
        out.with_file_name(format!(
            "{}{suffix}",
            out.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "masks".into())
        ))
    };
    let (masks, width, gains, bars, rendered_background) = if is_static {
        let data = neus::Dataset::load(&a.video)?;
        let pb = Task::start(observer, "object masks", 1);
        let (masks, stats) = crate::object_masks::compute(&data)?;
        pb.finish();
        tracing::info!(
            "the board as the views agree on it: {} of {} cells",
            stats.board_cells.0,
            stats.board_cells.1
        );
        (masks, data.width as usize, stats.gains, stats.bars, 0)
    } else {
        let Some(scene_run) = &a.scene else {
            fail!(
                Settings,
                "{}: a video's masks need the scene's training run (--scene RUN)",
                a.video.display()
            );
        };
        let scene =
            load_field(&checkpoint_of(scene_run)).with_context(|| format!("--scene {}", scene_run.display()))?;
        let ComputedMasks {
            masks,
            stats,
            rendered,
            width,
            ..
        } = compute(&a.video, &c, &scene, observer)?;
        // The rendering and the background it became, for inspection.
        let rgb = |img: &[[f32; 3]]| Image {
            width: width as u32,
            height: (img.len() / width) as u32,
            channels: 3,
            data: img.iter().flat_map(|c| c.map(crate::images::to8)).collect(),
        };
        pganeus_io::write_png(&beside_out("_scene.png"), &rgb(&rendered))?;
        pganeus_io::write_png(&beside_out("_background.png"), &rgb(&stats.background))?;
        (masks, width, stats.gains, stats.bars, stats.rendered_background)
    };
    write_masks(&out, &masks, width)?;
    let own = if is_static {
        c.masks.clone()
    } else {
        c.extra_masks
            .iter()
            .find(|(n, _)| *n == a.body)
            .map(|(_, m)| m.clone())
            .or(c.masks.clone())
    }
    .filter(|m| m.first().and_then(|p| p.parent()) != Some(out.as_path()));
    let against = match own {
        Some(paths) => Some(against(&masks, &paths)?),
        None => None,
    };
    let report = MasksReport {
        video: a.video.clone(),
        out: out.clone(),
        areas: masks.iter().map(|m| m.iter().filter(|&&v| v).count()).collect(),
        gains,
        bars,
        rendered_background,
        against,
    };
    let json = serde_json::to_vec_pretty(&report)?;
    let report_path = beside_out(".json");
    pganeus_io::write_atomic(&report_path, &json)?;
    if let Some(ag) = &report.against {
        let seen: Vec<f64> = ag
            .iou
            .iter()
            .zip(&ag.areas)
            .filter(|(_, &area)| area > 200)
            .map(|(&v, _)| v)
            .collect();
        let worst = seen.iter().copied().fold(f64::INFINITY, f64::min);
        tracing::info!(
            "against {}: IoU mean {:.3}, worst {:.3} over the {} {} where the body covers more than 200 pixels",
            ag.folder.display(),
            seen.iter().sum::<f64>() / seen.len().max(1) as f64,
            worst,
            seen.len(),
            if is_static { "views" } else { "frames" }
        );
    }
    tracing::info!(
        "wrote {} masks into {} and {}",
        masks.len(),
        out.display(),
        report_path.display()
    );
    Ok(report)
}

/// The computed `masks` against the mask files `paths` (one per image): each image's IoU and true area.
fn against(masks: &[Vec<bool>], paths: &[PathBuf]) -> Result<Against> {
    let folder = paths[0].parent().map(Path::to_path_buf).unwrap_or_default();
    let mut iou = Vec::new();
    let mut areas = Vec::new();
    for (m, p) in masks.iter().zip(paths) {
        let t = crate::images::read_mask(p)?;
        // Neither shows the body: they agree.
        let none = !m.iter().chain(&t).any(|&v| v);
        iou.push(if none { 1.0 } else { geom::coverage_iou(m, &t) });
        areas.push(t.iter().filter(|&&v| v).count());
    }
    Ok(Against { folder, iou, areas })
}
