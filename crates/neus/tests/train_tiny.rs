//! A tiny training run on a sphere rendered by the project lowers the colour
//! loss and brings the zero level near the true surface; checkpoints load,
//! resume exactly, and a truncated one is refused.
use geom::Vec3;
use neus::{checkpoint, Dataset, NeusTrainer, TrainConfig};
use std::path::{Path, PathBuf};

use crate::common;
use common::tiny_config;

fn scratch(name: &str) -> PathBuf {
    testkit::scratch_dir("neus", name)
}

/// A 3 cm ball alone on the board, 12 views of 64×48 with masks.
fn ball_capture(dir: &Path) -> (PathBuf, f64, Vec3<f64>) {
    ball_capture_sized(dir, 64, 48)
}

fn ball_capture_sized(dir: &Path, width: u32, height: u32) -> (PathBuf, f64, Vec3<f64>) {
    let mut scene = synth::preset("tabletop", synth::Scale::Small).unwrap();
    scene.bodies[0].shape = synth::desc::ShapeDesc::Sphere { radius: 0.03 };
    scene.cameras.width = width;
    scene.cameras.height = height;
    scene.cameras.views = 12;
    scene.videos.truncate(1);
    scene.videos[0].frames = 1;
    scene.videos[0].bodies[0].t = [-0.12, -0.02, 0.03];
    synth::generate(&scene, Path::new("."), dir, &mut |_, _, _| {}).unwrap();
    let truth = pganeus_io::read_truth(&dir.join("truth.json")).unwrap();
    let centre = Vec3::cst(truth.bodies[0].static_captures[0].pose.t);
    (dir.join("toy_a"), 0.03, centre)
}

#[test]
fn tiny_training_fits_a_ball() {
    let dir = scratch("ball");
    let (capture, r, centre) = ball_capture(&dir);
    let data = Dataset::load(&capture).unwrap();
    let (unit_c, unit_r) = (data.centre, data.radius);
    let mut t = NeusTrainer::new(tiny_config(), data).unwrap();
    let stats: Vec<_> = (0..300).map(|_| t.step()).collect();
    let first: f32 = stats[..30].iter().map(|s| s.loss.rgb).sum::<f32>() / 30.0;
    let last: f32 = stats[270..].iter().map(|s| s.loss.rgb).sum::<f32>() / 30.0;
    // Seeded and deterministic: measured 0.172 → 0.039 (0.23×).
    assert!(last < 0.35 * first, "colour L1 {first:.4} → {last:.4}");
    // The zero level against the true sphere: SDF at points of the true
    // surface, in world metres.
    let mut rng = geom::SplitMix64::new(3);
    let pts: Vec<f32> = (0..500)
        .flat_map(|_| {
            let mut d = rng.dir();
            d.z = d.z.abs().max(0.2); // the visible upper part (the board hides the bottom)
            let d = d.normalize_or(Vec3::new(0.0, 0.0, 1.0));
            let p = (centre + d * r - unit_c) * (1.0 / unit_r);
            p.to_array().map(|v| v as f32)
        })
        .collect();
    let sdf = t.field.sdf_values(&pts, t.config.field.grid.levels);
    let mean_err = sdf.iter().map(|s| (*s as f64).abs() * unit_r).sum::<f64>() / sdf.len() as f64;
    eprintln!(
        "colour L1 {first:.4} -> {last:.4}; mean |SDF| on the true surface {:.2} mm",
        mean_err * 1e3
    );
    assert!(
        mean_err < 0.0015, // measured 0.69 mm; a pixel of these 64×48 views spans about 1–1.5 mm on the ball
        "mean |SDF| on the true surface: {:.2} mm",
        mean_err * 1e3
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A mask labels each pixel by what its centre sees. Rays through random points of their pixels are taught
/// that the outer corner of a pixel marked "ball" is opaque though it misses the ball, so the drawn
/// silhouette grows, and a fit from such a field puts the body too far from the camera. Rays through pixel
/// centres (the object default) are not. It takes a sharp field to show: the default config, 800 steps.
#[test]
#[ignore = "slow: an object field trained 800 steps with the default settings keeps its silhouette to the masks, ~95 s"]
fn rays_through_pixel_centres_keep_the_silhouette_to_the_masks() {
    let dir = scratch("ball_silhouette");
    let (capture, _, _) = ball_capture_sized(&dir, 160, 120);
    let cfg = TrainConfig {
        holdout_every: 6,
        ..TrainConfig::default()
    };
    assert!(!cfg.pixel_jitter, "objects train through pixel centres by default");
    let mut t = NeusTrainer::new(cfg, Dataset::load(&capture).unwrap()).unwrap();
    for _ in 0..800 {
        t.step();
    }
    let every: Vec<usize> = (0..t.data.views.len()).collect();
    let s = neus::holdout::score(&t, &every).silhouette;
    let excess = s.area_excess_percent().expect("an object capture with masks");
    let iou = s.iou();
    eprintln!("silhouette area against the masks {excess:+.2} %, IoU {iou:.4}");
    // Measured +1.00 %, IoU 0.9904; with `pixel_jitter = true` (as before) +3.83 %, IoU 0.9643.
    assert!(excess.abs() < 2.0, "silhouette area {excess:+.2} % of the masks'");
    assert!(iou > 0.985, "silhouette IoU {iou:.4}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn checkpoints_round_trip_resume_exactly_and_refuse_truncation() {
    round_trip("ckpt", tiny_config());
}

/// The same for a scene field: the background field's parameters and Adam state round-trip too (on the
/// ball's masked capture, whose masks then mark what is not scene).
#[test]
fn scene_checkpoints_round_trip_with_the_background_field() {
    let mut cfg = tiny_config();
    cfg.kind = neus::CaptureSubject::Scene;
    cfg.field.init = neus::FieldInit::Board;
    cfg.field.background = Some(neus::background_field::BackgroundConfig {
        grid: field::HashGridConfig {
            levels: 4,
            log2_table_size: 12,
            max_resolution: 64,
            ..Default::default()
        },
        samples: 8,
        ..Default::default()
    });
    // The checkpoint (step 20 of 30) falls inside the averaging window (steps 16–30): the running mean
    // round-trips too, or the resumed run's final field would differ.
    cfg.average_last = 0.5;
    round_trip("ckpt_scene", cfg);
}

/// With `average_last`, the trained field is the mean of the last steps' parameters, and every step before
/// the last is the same as without averaging.
#[test]
fn the_last_steps_are_averaged_into_the_field() {
    let dir = scratch("average");
    let (capture, _, _) = ball_capture(&dir);
    let mut cfg = tiny_config();
    cfg.iterations = 12;
    cfg.average_last = 0.25; // the results of steps 10, 11 and 12
    let plain_cfg = TrainConfig {
        average_last: 0.0,
        ..cfg.clone()
    };
    let mut plain = NeusTrainer::new(plain_cfg, Dataset::load(&capture).unwrap()).unwrap();
    let mut averaged = NeusTrainer::new(cfg, Dataset::load(&capture).unwrap()).unwrap();
    let mut iterates: Vec<Vec<Vec<f32>>> = Vec::new();
    for step in 1..=12 {
        plain.step();
        averaged.step();
        if step >= 10 {
            iterates.push(plain.field.params().iter().map(|(_, p)| p.to_vec()).collect());
        }
        if step < 12 {
            assert_eq!(averaged.field.params(), plain.field.params(), "step {step}");
        }
    }
    assert_ne!(averaged.field.sdf_params, plain.field.sdf_params);
    for (k, (_, p)) in averaged.field.params().iter().enumerate() {
        for (i, &v) in p.iter().enumerate() {
            let mean = (iterates[0][k][i] + iterates[1][k][i] + iterates[2][k][i]) / 3.0;
            assert!(
                (v - mean).abs() <= 1e-6 * (1.0 + mean.abs()),
                "parameter {i} of vector {k}: {v} against the mean {mean}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// With `sample_band`, a step past the warm-up keeps only the samples near the surface, fewer than every
/// sample in an occupied cell (this early, with 1/s still wide, about 80 % of them); the steps before the
/// grid is in use are the same.
#[test]
fn a_step_keeps_the_samples_near_the_surface() {
    let dir = scratch("band");
    let (capture, _, _) = ball_capture(&dir);
    let mut cfg = tiny_config();
    cfg.occupancy_warmup = 8;
    cfg.occupancy_every = 4;
    let banded_cfg = TrainConfig {
        sample_band: 0.5,
        ..cfg.clone()
    };
    let mut plain = NeusTrainer::new(cfg, Dataset::load(&capture).unwrap()).unwrap();
    let mut banded = NeusTrainer::new(banded_cfg, Dataset::load(&capture).unwrap()).unwrap();
    let (mut all, mut near) = (0, 0);
    for step in 1..=40 {
        let (p, b) = (plain.step(), banded.step());
        if step <= 8 {
            assert_eq!(p.samples, b.samples, "step {step}: the grid is not in use yet");
        } else if step > 24 {
            all += p.samples;
            near += b.samples;
        }
    }
    assert!(
        near > 0 && 10 * near < 9 * all,
        "{near} samples near the surface against {all}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn round_trip(name: &str, mut cfg: TrainConfig) {
    let dir = scratch(name);
    let (capture, _, _) = ball_capture(&dir);
    cfg.iterations = 30;
    // Refresh the occupancy grid before and after the checkpoint, so that its
    // state is part of what must round-trip.
    cfg.occupancy_warmup = 8;
    cfg.occupancy_every = 4;
    // Keep only the samples near the surface (a scene's default): where the refresh placed it is state too.
    cfg.sample_band = 0.5;
    let mut straight = NeusTrainer::new(cfg.clone(), Dataset::load(&capture).unwrap()).unwrap();
    for _ in 0..30 {
        straight.step();
    }
    let mut first = NeusTrainer::new(cfg, Dataset::load(&capture).unwrap()).unwrap();
    for _ in 0..20 {
        first.step();
    }
    let path = dir.join("ckpt.safetensors");
    checkpoint::save(&first, &path).unwrap();
    let loaded = checkpoint::load_field(&path).unwrap();
    assert_eq!(loaded.field.sdf_params, first.field.sdf_params);
    assert_eq!(loaded.step, 20);
    drop(first); // as if the process were killed here
    let mut resumed = checkpoint::resume(&path, Dataset::load(&capture).unwrap()).unwrap();
    for _ in 0..10 {
        resumed.step();
    }
    assert_eq!(
        resumed.field.grid_params, straight.field.grid_params,
        "resumed training must match uninterrupted training"
    );
    assert_eq!(resumed.field.sdf_params, straight.field.sdf_params);
    assert_eq!(resumed.field.color_params, straight.field.color_params);
    assert_eq!(resumed.field.extra, straight.field.extra);
    match (&resumed.field.background, &straight.field.background) {
        (Some(a), Some(b)) => {
            assert_eq!(a.grid_params, b.grid_params);
            assert_eq!(a.density_params, b.density_params);
            assert_eq!(a.color_params, b.color_params);
        }
        (None, None) => {}
        _ => panic!("the background field did not survive the checkpoint"),
    }
    assert_eq!(resumed.occupancy.cells(), straight.occupancy.cells());
    // Where the refresh put the surface inside the cells decides which samples a step keeps (`sample_band`).
    let bits = |t: &NeusTrainer| t.centre_sdf.values().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&resumed) == bits(&straight),
        "the SDF at the cells' centres must round-trip"
    );
    assert!(
        straight.occupancy.cells().contains(&0),
        "the grid should have been refreshed (some cells empty)"
    );
    // A truncated checkpoint is an error, not a panic.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.join("cut.safetensors");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let err = checkpoint::load_field(&cut)
        .err()
        .expect("truncated checkpoint must fail")
        .to_string();
    assert!(err.contains("cut.safetensors"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
