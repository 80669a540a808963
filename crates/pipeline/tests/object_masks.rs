//! An object capture's masks computed from its photos alone (`pipeline::object_masks`, the board the views
//! agree on and the views agreeing on what stands on it) against the masks `synth` renders, on camera-like
//! photos (exposure and white balance per photo, noise, JPEG); and `train` computing them for an object
//! capture that has none.

use crate::common;
use pipeline::images::read_mask;
use pipeline::Quiet;
use synth::{preset, CameraLike, Scale};

const VIEWS: usize = 16;

/// The tabletop's toy in camera-like photos (one short video beside it: `synth` needs one), rendered once
/// for the tests that share it.
fn capture() -> &'static std::path::Path {
    static DIR: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let mut s = preset("tabletop", Scale::Small).unwrap();
        s.cameras.views = VIEWS;
        s.videos.truncate(1);
        s.videos[0].frames = 2;
        s.camera_like = Some(CameraLike::default());
        common::synth_into(&s, "object_masks", "camera-like")
    })
}

#[test]
fn masks_from_an_object_captures_photos_match_the_true_ones() {
    let dir = capture().join("toy_a");
    let data = neus::Dataset::load(&dir).unwrap();
    let (masks, stats) = pipeline::object_masks::compute(&data).unwrap();
    let scores: Vec<f64> = masks
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let t = read_mask(&dir.join("mask").join(format!("{i:03}.png"))).unwrap();
            geom::coverage_iou(m, &t)
        })
        .collect();
    let mean = scores.iter().sum::<f64>() / scores.len() as f64;
    let worst = scores.iter().copied().fold(1.0, f64::min);
    eprintln!("IoU per view {scores:.3?}; {stats:?}");
    // Measured 2026-12-06: mean 0.974, worst 0.934 (the bar is 0.95 in every view: met on the
    // demo's 24 views, docs/commands/masks.md; 16 views here).
    assert!(mean > 0.96 && worst > 0.93, "mean {mean:.3}, worst {worst:.3}");
}

#[test]
fn train_computes_an_object_captures_missing_masks_and_writes_them() {
    let root = capture();
    let bare = testkit::scratch_dir("object_masks", "no_masks");
    for item in ["image", "cameras_sphere.npz", "capture.json"] {
        let (from, to) = (root.join("toy_a").join(item), bare.join(item));
        if from.is_dir() {
            std::fs::create_dir_all(&to).unwrap();
            for f in std::fs::read_dir(&from).unwrap() {
                let f = f.unwrap().path();
                std::fs::copy(&f, to.join(f.file_name().unwrap())).unwrap();
            }
        } else {
            std::fs::copy(&from, &to).unwrap();
        }
    }
    let out = testkit::scratch_dir("object_masks", "no_masks_run");
    let mut args = pipeline::train::TrainArgs::new(bare.clone(), out.clone());
    args.iterations = Some(20);
    args.no_preview = true;
    args.force = true;
    pipeline::train::run(&args, &Quiet).unwrap();
    let written: Vec<_> = std::fs::read_dir(out.join("mask")).unwrap().collect();
    assert_eq!(
        written.len(),
        VIEWS,
        "one mask a view in {}",
        out.join("mask").display()
    );
    let computed = read_mask(&out.join("mask/000.png")).unwrap();
    let truth = read_mask(&root.join("toy_a/mask/000.png")).unwrap();
    let iou = geom::coverage_iou(&computed, &truth);
    assert!(iou > 0.9, "IoU {iou:.3}");
    assert!(!bare.join("mask").exists(), "the capture is left as it was");
}
