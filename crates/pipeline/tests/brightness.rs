//! The brightness drift a fit reads off the scene (`recon::brightness_drift`) against the drift a camera-like
//! video was developed with (`truth.json`'s `image_gains`, carried onto the stored values as `eval` carries
//! it): a phone's auto exposure swinging over the video, with noise, JPEG and motion blur on top. The scene
//! behind the body is its clean render, as a trained scene field renders it. On the tabletop, and (slow) on
//! the `backdrop` variant: another light, board and a plain grey world beyond it.

use crate::common;
use pipeline::images::{read_mask, reference_frame};
use std::path::{Path, PathBuf};
use synth::{preset, CameraLike, Scale, SynthScene};

const FRAMES: usize = 12;

fn scene(name: &str, camera_like: Option<CameraLike>) -> SynthScene {
    let mut s = preset(name, Scale::Small).unwrap();
    s.cameras.width = 96;
    s.cameras.height = 72;
    s.cameras.views = 2;
    // The drop: a body tumbling through the view, its blur reaching past its mask.
    s.videos.retain(|v| v.name == "drop");
    s.videos[0].frames = FRAMES;
    s.camera_like = camera_like;
    s
}

fn generate(scene: &SynthScene, name: &str) -> PathBuf {
    common::synth_into(scene, "brightness", name)
}

/// The drift read off the preset's camera-like drop, each frame's error against the truth's.
fn drift_errors(preset: &str) -> Vec<f64> {
    let clean = generate(&scene(preset, None), &format!("{preset}-clean"));
    let camera = CameraLike {
        exposure_drift: 0.12,
        ..CameraLike::default()
    };
    assert!(camera.noise > 0.0 && camera.jpeg_quality < 100 && camera.shutter > 0.0);
    let raw = generate(&scene(preset, Some(camera)), &format!("{preset}-camera-like"));
    let file = |dir: &Path, sub: &str, k: usize| dir.join("drop").join(sub).join(synth::frame_name(k, FRAMES));

    let frames: Vec<Vec<[f32; 3]>> = (0..FRAMES)
        .map(|k| reference_frame(&file(&raw, "image", k)).unwrap())
        .collect();
    let masks: Vec<Vec<bool>> = (0..FRAMES)
        .map(|k| read_mask(&file(&raw, "mask", k)).unwrap())
        .collect();
    // The clean first frame stands for the empty scene: its body's pixels are left out of every frame.
    let backdrop = reference_frame(&file(&clean, "image", 0)).unwrap();
    let bodies: Vec<Vec<bool>> = masks
        .iter()
        .map(|m| m.iter().zip(&masks[0]).map(|(a, b)| *a || *b).collect())
        .collect();
    let rgb: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
    let measured = recon::brightness_drift(&rgb, &bodies, &backdrop, 96);

    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(raw.join("truth.json")).unwrap()).unwrap();
    let gains: Vec<[f64; 3]> = serde_json::from_value(truth[synth::IMAGE_GAINS]["drop"].clone()).unwrap();
    let expected = pipeline::eval::true_brightness_drift(&gains);
    assert_eq!((measured.len(), expected.len()), (FRAMES, FRAMES));
    eprintln!("{preset}: measured {measured:.4?}\nexpected {expected:.4?}");
    let swing = expected.iter().cloned().fold(0.0f64, |m, e| m.max((e - 1.0).abs()));
    assert!(
        swing > 0.02,
        "{preset}: the video drifts enough to measure: {expected:?}"
    );
    measured
        .iter()
        .zip(&expected)
        .map(|(m, e)| (m / e - 1.0).abs())
        .collect()
}

#[test]
fn a_drifting_auto_exposure_is_read_off_the_scene_within_half_a_percent() {
    for (k, e) in drift_errors("tabletop").iter().enumerate() {
        assert!(*e < 0.005, "frame {k}: {:.2} % off the truth's", 100.0 * e);
    }
}

#[test]
#[ignore = "slow: the backdrop variant's camera-like drop, rendered twice (about 20 s)"]
fn on_the_backdrop_variant_too() {
    for (k, e) in drift_errors("backdrop").iter().enumerate() {
        assert!(*e < 0.005, "frame {k}: {:.2} % off the truth's", 100.0 * e);
    }
}
