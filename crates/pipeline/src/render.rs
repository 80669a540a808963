//! `render`: a trained field's views, depth and normals from a capture's or a file's cameras, with PSNR
//! against the capture (the switching render of Eq. 3–4 with `other`); with a trajectory, objects moving in
//! their scene (`render_trajectory`).

use crate::cameras::{read_cameras, read_transform};
use crate::error::{err, fail};
use crate::images::to8;
use crate::run_folder::checkpoint_of;
use crate::Result;
use crate::{note, Observer, Task};
use geom::Camera;
use geom::Vec3;
use neus::checkpoint::load_field;
use neus::holdout::SilhouetteTally;
use neus::render_view::{psnr, render_view, RenderSettings};
use neus::switching::{route, Route};
use neus::Dataset;
use pganeus_io::Image;
use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[cfg_attr(
    feature = "clap",
    command(after_help = "Examples:
  pganeus render runs/toy_a --views data/tabletop/toy_a --out renders/toy_a
  pganeus render --trajectory fits/slide/trajectory.json --scene runs/scene --object toy=merged/toy --views data/tabletop/slide --out renders/slide")
)]
pub struct RenderArgs {
    /// A run folder (from `pganeus train`) or its checkpoint file (not with --trajectory).
    #[cfg_attr(
        feature = "clap",
        arg(required_unless_present = "trajectory", conflicts_with = "trajectory")
    )]
    pub run: Option<PathBuf>,
    /// Render every frame of a motion: a trajectory.json (from simulate, target, fit-physics) or a
    /// truth.json (pick the video with --video), with each body's reconstructed object (--object) at its
    /// poses inside the reconstructed scene (--scene); writes a video capture in the NeuS layout.
    #[cfg_attr(feature = "clap", arg(long, requires = "object"))]
    pub trajectory: Option<PathBuf>,
    /// With a truth.json trajectory: the video whose poses to render.
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory"))]
    pub video: Option<String>,
    /// The scene's run folder (train --kind scene); without it, objects over white.
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory"))]
    pub scene: Option<PathBuf>,
    /// NAME=DIR: the body NAME of the trajectory is the object in DIR (a merge output or a run folder).
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory"))]
    pub object: Vec<String>,
    /// With --trajectory: the animation shows this capture's images beside the rendering.
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory"))]
    pub side_by_side: Option<PathBuf>,
    /// With --trajectory: a novel view, the cameras turned by DEG degrees about the world's vertical axis
    /// (through the board's origin), at the same height and distance.
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory", allow_hyphen_values = true))]
    pub orbit: Option<f64>,
    /// With --trajectory and a fixed camera: trace every field along every ray in every frame (the
    /// reference), instead of compositing the objects over the scene rendered once.
    #[cfg_attr(feature = "clap", arg(long, requires = "trajectory"))]
    pub reference_compositing: bool,
    /// Render every view of this capture and print PSNR against its images.
    #[cfg_attr(feature = "clap", arg(long, conflicts_with = "camera"))]
    pub views: Option<PathBuf>,
    /// Render the cameras of a JSON file (one object or a list): `{"width", "height",
    /// "world_mat": 4×4}` (NeuS: K·W2C) or `{"width", "height", "K": 3×3, "world_to_cam": 4×4}`, world coordinates.
    #[cfg_attr(feature = "clap", arg(long))]
    pub camera: Option<PathBuf>,
    /// Where to write rgb/, depth/ (PNG and .npy) and normal/.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: PathBuf,
    /// Switching render (Eq. 3–4): the run of the same object in its other pose. Cameras below
    /// the board (z < 0 in RUN's frame) render this field instead, through `--transform`.
    #[cfg_attr(feature = "clap", arg(long, requires = "transform"))]
    pub other: Option<PathBuf>,
    /// The `transform.json` written by `pganeus merge OTHER RUN`: `p_run = R_1to2 · p_other + T_1to2`.
    #[cfg_attr(feature = "clap", arg(long, requires = "other"))]
    pub transform: Option<PathBuf>,
}

impl RenderArgs {
    /// A render into `out` with nothing else given: set `run` (a field's views) or `trajectory` and
    /// `object` (a motion), and the cameras (`views` or `camera`).
    pub fn new(out: PathBuf) -> RenderArgs {
        RenderArgs {
            run: None,
            trajectory: None,
            video: None,
            scene: None,
            object: Vec::new(),
            side_by_side: None,
            orbit: None,
            reference_compositing: false,
            views: None,
            camera: None,
            out,
            other: None,
            transform: None,
        }
    }
}

/// An image to compare a render with, and its mask.
struct Reference<'a> {
    rgb: &'a [[f32; 3]],
    mask: Option<&'a [f32]>,
}

/// A view to render: its name, its camera in world coordinates, and the image to compare with.
struct Job<'a> {
    name: String,
    camera: Camera<f64>,
    reference: Option<Reference<'a>>,
}

pub fn run(a: &RenderArgs, observer: &dyn Observer) -> Result<()> {
    // Written beside --out and swapped in whole: a failure part-way leaves the old folder as it was.
    let staged = pganeus_io::StagedDir::new(&a.out)?;
    let out = staged.path().to_path_buf();
    if let Some(trajectory) = &a.trajectory {
        super::render_trajectory::run(
            super::render_trajectory::TrajectoryJob {
                trajectory,
                video: a.video.as_deref(),
                scene: a.scene.as_deref(),
                objects: &a.object,
                views: a.views.as_deref(),
                camera: a.camera.as_deref(),
                side_by_side: a.side_by_side.as_deref(),
                orbit_deg: a.orbit,
                reference_compositing: a.reference_compositing,
                out: &out,
                shown_as: &a.out,
            },
            observer,
        )?;
        staged.commit()?;
        return Ok(());
    }
    let run = a
        .run
        .as_deref()
        .ok_or_else(|| err!(Settings, "render: give a run folder, or --trajectory"))?;
    let l = load_field(&checkpoint_of(run))?;
    let data = match &a.views {
        Some(capture) => Some(Dataset::load(capture)?),
        None => None,
    };
    let mut jobs = Vec::new();
    if let Some(data) = &data {
        for v in &data.views {
            // Back to the world through the capture's own scale_mat, then into the field's frame.
            let world = v.camera.from_unit_frame(data.centre, data.radius);
            jobs.push(Job {
                name: v.name.clone(),
                camera: world,
                reference: Some(Reference {
                    rgb: &v.rgb,
                    mask: v.mask.as_deref(),
                }),
            });
        }
    } else if let Some(path) = &a.camera {
        for (i, c) in read_cameras(path)?.iter().enumerate() {
            jobs.push(Job {
                name: format!("cam_{i:03}"),
                camera: *c,
                reference: None,
            });
        }
    } else {
        fail!(Stage, "give --views <capture> or --camera <json>");
    }
    let other = match (&a.other, &a.transform) {
        (Some(run), Some(t)) => Some((load_field(&checkpoint_of(run))?, read_transform(t)?.inverse())),
        _ => None,
    };
    let mut psnrs = Vec::new();
    // An object's opacity against the capture's masks (a scene's masks mark what is not scene).
    let object = l.config.kind == neus::CaptureSubject::Object && other.is_none();
    let mut silhouettes = SilhouetteTally::default();
    let pb = Task::start(observer, "views", jobs.len() as u64);
    for job in &jobs {
        pb.inc(1);
        // Eq. 4: the other field renders cameras below the primary's board.
        let (field, camera, to_primary) = match &other {
            Some((lo, primary_to_other)) => match route(&job.camera, primary_to_other) {
                Route::Primary => (&l, job.camera, None),
                Route::Other(moved) => (lo, moved, Some(primary_to_other.q.conj())),
            },
            None => (&l, job.camera, None),
        };
        let mut img = render_view(
            &field.field,
            &field.occupancy,
            &RenderSettings::of(field),
            &camera.in_unit_frame(field.centre, field.radius),
        );
        if let Some(q) = to_primary {
            for n in &mut img.normal {
                *n = q.rotate(Vec3::cst(n.map(f64::from))).to_array().map(|v| v as f32);
            }
        }
        let (w, h) = (img.width, img.height);
        let mut rgb = Image::new(w, h, 3);
        let mut nrm = Image::new(w, h, 3);
        let mut dep = Image::new(w, h, 1);
        let dmax = img.depth.iter().cloned().fold(1e-6f32, f32::max);
        for p in 0..(w * h) as usize {
            rgb.data[p * 3..p * 3 + 3].copy_from_slice(&img.rgb[p].map(to8));
            nrm.data[p * 3..p * 3 + 3].copy_from_slice(&img.normal[p].map(|c| to8(0.5 + 0.5 * c)));
            dep.data[p] = to8(img.depth[p] / dmax);
        }
        let name = format!("{}.png", job.name);
        pganeus_io::write_png(&out.join("rgb").join(&name), &rgb)?;
        pganeus_io::write_png(&out.join("normal").join(&name), &nrm)?;
        pganeus_io::write_png(&out.join("depth").join(&name), &dep)?;
        let metres: Vec<f32> = img.depth.iter().map(|d| d * field.radius as f32).collect();
        pganeus_io::write_npy(
            &out.join("depth").join(format!("{}.npy", job.name)),
            &pganeus_io::NpyArray::new(vec![h as usize, w as usize], pganeus_io::NpyData::F32(metres)),
        )?;
        let line = match job.reference {
            Some(Reference { rgb: gt, mask }) => {
                // A field trained with per-view appearance renders the views' mean exposure: each view is
                // scored on its right half through a colour map fitted on its left half, as training's
                // held-out views are.
                let p = if field.config.per_view_appearance {
                    neus::appearance::psnr_right_half(&img.rgb, gt, mask, img.width as usize)
                } else {
                    psnr(&img.rgb, gt, mask)
                };
                psnrs.push(p);
                let mut one = SilhouetteTally::default();
                if let (true, Some(m)) = (object, mask) {
                    one.add(&img.opacity, m);
                    silhouettes.merge(&one);
                }
                match one.area_excess_percent() {
                    Some(area) => format!(
                        "{}: PSNR {p:.2} dB, silhouette area {area:+.2} %, IoU {:.4}",
                        job.name,
                        one.iou()
                    ),
                    None => format!("{}: PSNR {p:.2} dB", job.name),
                }
            }
            None if to_primary.is_some() => {
                format!("{}: rendered by the other field (camera below the board)", job.name)
            }
            None => format!("{}: rendered", job.name),
        };
        note(observer, line);
    }
    pb.finish();
    if !psnrs.is_empty() {
        note(
            observer,
            format!(
                "mean PSNR {:.2} dB over {} views{}",
                psnrs.iter().sum::<f32>() / psnrs.len() as f32,
                psnrs.len(),
                if data.as_ref().is_some_and(|d| d.has_masks()) {
                    " (inside the masks)"
                } else {
                    ""
                }
            ),
        );
    }
    if let Some(excess) = silhouettes.area_excess_percent() {
        note(
            observer,
            format!(
                "silhouette: area {excess:+.2} % of the masks', IoU {:.4} (opacity > 0.5)",
                silhouettes.iou()
            ),
        );
    }
    staged.commit()?;
    note(observer, format!("wrote {}", a.out.display()));
    Ok(())
}
