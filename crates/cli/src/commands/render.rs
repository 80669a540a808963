use anyhow::{bail, Result};
use clap::Args;
use geom::{TriMesh, Vec3};
use neus::checkpoint::{load_field, LoadedField};
use neus::render_view::{psnr, render_view, RenderSettings};
use neus::{Dataset, NeusField, NeusTrainer};
use pganeus_io::Image;
use std::path::PathBuf;

#[derive(Args)]
pub struct RenderArgs {
    /// A run folder (from `pganeus train`) or its checkpoint file.
    pub run: PathBuf,
    /// Render every view of this capture and print PSNR against its images.
    #[arg(long)]
    pub views: Option<PathBuf>,
    /// Where to write rgb/, depth/ (PNG and .npy) and normal/.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn settings(l: &LoadedField) -> RenderSettings {
    let c = &l.config;
    let g = &c.field.grid;
    RenderSettings {
        steps_per_ray: c.steps_per_ray * 2,
        max_samples_per_ray: c.max_samples_per_ray * 2,
        active_levels: g.levels,
        fd_eps: 2.0 / g.max_resolution as f32,
    }
}

/// Mean PSNR of a trainer's held-out views (inside the masks when there are masks).
pub fn holdout_psnr(t: &NeusTrainer) -> f32 {
    let g = &t.config.field.grid;
    let set = RenderSettings {
        steps_per_ray: t.config.steps_per_ray * 2,
        max_samples_per_ray: t.config.max_samples_per_ray * 2,
        active_levels: t.config.active_levels(t.step),
        fd_eps: t
            .fd_eps(t.config.active_levels(t.step))
            .min(2.0 / g.max_resolution as f32 * 4.0),
    };
    let views = &t.holdout_views;
    let sum: f32 = views
        .iter()
        .map(|&i| {
            let v = &t.data.views[i];
            let img = render_view(&t.field, &t.occupancy, &set, &v.camera);
            psnr(&img.rgb, &v.rgb, v.mask.as_deref())
        })
        .sum();
    sum / views.len().max(1) as f32
}

/// The zero level of a field inside the unit sphere's cube, in world
/// coordinates (`p_world = centre + radius · p_unit`).
pub fn zero_level_mesh(field: &NeusField, levels: usize, centre: Vec3<f64>, radius: f64, res: usize) -> TriMesh {
    let grid = mesh::sample_sdf_grid(
        &|pts: &[[f64; 3]]| {
            let flat: Vec<f32> = pts.iter().flatten().map(|v| *v as f32).collect();
            field.sdf_values(&flat, levels)
        },
        [-1.0; 3],
        [1.0; 3],
        res,
    );
    let mut m = mesh::extract_zero_level(&grid);
    for v in &mut m.vertices {
        *v = (centre + Vec3::cst(*v) * radius).to_array();
    }
    m
}

fn to8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

pub fn run(a: RenderArgs) -> Result<()> {
    let ckpt = if a.run.is_dir() {
        a.run.join("checkpoint.safetensors")
    } else {
        a.run.clone()
    };
    let l = load_field(&ckpt)?;
    let Some(capture) = a.views.clone() else {
        bail!("give --views <capture> (the cameras to render)")
    };
    let data = Dataset::load(&capture)?;
    if (data.centre - l.centre).norm() > 1e-9 * l.radius || (data.radius - l.radius).abs() > 1e-9 * l.radius {
        tracing::warn!(
            "{}: its scale_mat differs from the training capture's; rendering in the training frame",
            capture.display()
        );
    }
    let set = settings(&l);
    let mut psnrs = Vec::new();
    for (i, v) in data.views.iter().enumerate() {
        // The view's camera in the field's unit frame (the capture's own scale_mat may differ).
        let mut cam = v.camera;
        let world_t = (cam.world_to_cam.t * data.radius) - cam.world_to_cam.q.rotate(data.centre);
        cam.world_to_cam.t = (world_t + cam.world_to_cam.q.rotate(l.centre)) * (1.0 / l.radius);
        let img = render_view(&l.field, &l.occupancy, &set, &cam);
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
        let name = format!("{}.png", v.name);
        pganeus_io::write_png(&a.out.join("rgb").join(&name), &rgb)?;
        pganeus_io::write_png(&a.out.join("normal").join(&name), &nrm)?;
        pganeus_io::write_png(&a.out.join("depth").join(&name), &dep)?;
        let metres: Vec<f32> = img.depth.iter().map(|d| d * l.radius as f32).collect();
        pganeus_io::write_npy(
            &a.out.join("depth").join(format!("{}.npy", v.name)),
            &pganeus_io::NpyArray::new(vec![h as usize, w as usize], pganeus_io::NpyData::F32(metres)),
        )?;
        let p = psnr(&img.rgb, &v.rgb, v.mask.as_deref());
        println!("view {i} ({}): PSNR {p:.2} dB", v.name);
        psnrs.push(p);
    }
    println!(
        "mean PSNR {:.2} dB over {} views{}",
        psnrs.iter().sum::<f32>() / psnrs.len().max(1) as f32,
        psnrs.len(),
        if data.has_masks() { " (inside the masks)" } else { "" }
    );
    Ok(())
}
